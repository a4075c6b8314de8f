import sys

from nrmlc.cli import console_main

sys.exit(console_main())
