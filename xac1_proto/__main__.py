"""``python -m xac1_proto`` is the ``xac1`` console script."""

import sys

from .cli import main

sys.exit(main())
