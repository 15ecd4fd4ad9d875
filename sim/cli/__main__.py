"""`python -m sim.cli`: the command line without the console script."""

import sys

from sim.cli.entry import leave, main

sys.exit(leave(main()))
