"""``python -m twoscale ...`` runs the command line (same as the ``twoscale`` script)."""

from .cli.main import main

raise SystemExit(main())
