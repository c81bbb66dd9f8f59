"""``python -m granchain.accuracy measure|figure|model``."""
import sys

from .cli import main

sys.exit(main(prog="python -m granchain.accuracy"))
