"""``python -m pymr``: the same as the ``pymr`` console script."""
from .cli import main

raise SystemExit(main())
