"""``python -m impact_fenics.bench [--quick|--smoke|--mode M] [--parts ...] [--out ...]``: see run.py."""
from .run import main

main()
