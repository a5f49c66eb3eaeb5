import sys

from sinsalign.cli import main

sys.exit(main())
