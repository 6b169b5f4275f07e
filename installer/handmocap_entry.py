"""Entry point of the frozen application: the ``handmocap`` command (GUI when no subcommand is given)."""

import multiprocessing
import sys

if __name__ == "__main__":
    multiprocessing.freeze_support()  # Dask's local workers are spawned processes of this executable
    from handmocap.app.cli.main import main

    sys.exit(main())
