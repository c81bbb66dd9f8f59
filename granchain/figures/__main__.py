"""``python -m granchain.figures``: see :func:`granchain.figures.main`."""
import sys

from . import main

sys.exit(main())
