"""``python -m redundik``: the ``redundik`` command (:func:`redundik.cli.main.main`), for an environment whose scripts
folder is not on PATH."""

from __future__ import annotations

import sys

from redundik.cli.main import main

if __name__ == "__main__":
    sys.exit(main())
