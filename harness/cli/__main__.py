"""``python -m harness.cli``: the ``shadowbench`` command."""

import sys

from . import main

sys.exit(main())
