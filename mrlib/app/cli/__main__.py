"""``python -m mrlib.app.cli``: the ``mrlib`` command."""

import sys

from mrlib.app.cli import main

sys.exit(main())
