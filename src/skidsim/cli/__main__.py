"""``python -m skidsim.cli``: the ``skidsim`` command."""

import sys

from . import main

sys.exit(main())
