import sys

from scanamp.cli import main

sys.exit(main())
