"""``python -m xac1_proto`` is the ``xac1`` console script."""

import sys

from .entry import main

sys.exit(main())
