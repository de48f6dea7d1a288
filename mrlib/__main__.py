import sys

from mrlib.cli import main

sys.exit(main())
