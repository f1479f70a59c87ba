"""``python -m scart`` behaves exactly like the ``scart`` console script."""

import sys

from scart.cli import main

sys.exit(main())
