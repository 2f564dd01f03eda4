"""`python -m pamd` and the `pamd` console script run the command-line interface.

The CLI is imported in `main`, not at the top: a process started by multiprocessing's
spawn (the io process) runs the parent's main module again, as `__mp_main__`, and this
module is that main module (the console script imports `main` from here). So the io
process does not import the whole CLI, and through it the controller and the models.
"""

from __future__ import annotations


def main() -> int:
    from pamd.client.cli.main import main as cli_main  # see the module's doc (LAZY_OWN)

    return cli_main()


if __name__ == "__main__":
    raise SystemExit(main())
