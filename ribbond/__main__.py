"""``python -m ribbond``: the daemon (as the ``ribbond`` console script)."""

import sys

from .daemon import main

sys.exit(main())
