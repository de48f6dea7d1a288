import sys

from mrlib.app.cli import main

sys.exit(main())
