import sys

from nrmlc.cli import main

sys.exit(main())
