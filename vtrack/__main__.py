import sys

from vtrack.cli import main

sys.exit(main())
