"""``python -m impact_fenics run SCENE.toml`` and ``... plot RUN_DIR``: see impact_fenics.cli."""
from .cli import main

raise SystemExit(main())
