"""`python -m sim.cli`: the command line without the console script."""

import sys

from sim.cli.entry import main

sys.exit(main())
