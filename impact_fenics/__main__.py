"""``python -m impact_fenics run SCENE.toml`` and ``... plot RUN_DIR``: see impact_fenics.cli."""
from . import interrupts

with interrupts.held_at_start():  # a signal before main() installs the handling: one line
    from .cli import main

raise SystemExit(main())
