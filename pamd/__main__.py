"""`python -m pamd` runs the command-line interface."""

from pamd.cli.main import main

raise SystemExit(main())
