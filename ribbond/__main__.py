"""``python -m ribbond``: the daemon (as the ``ribbond`` console script)."""

import sys

from ribbond.daemon.main import main

sys.exit(main())
