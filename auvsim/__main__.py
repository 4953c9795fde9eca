import sys

from auvsim.cli import main

sys.exit(main())
