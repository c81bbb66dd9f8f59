"""``python -m granchain.thesis``: see :func:`granchain.thesis.main`."""
import sys

from . import main

sys.exit(main())
