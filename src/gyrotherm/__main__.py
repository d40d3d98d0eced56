"""``python -m gyrotherm`` runs the command-line interface."""

from gyrotherm.cli import main

raise SystemExit(main())
