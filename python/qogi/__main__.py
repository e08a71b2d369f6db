import sys

from .apps.console import main

sys.exit(main())
