import sys

from dexaug.cli import main

sys.exit(main())
