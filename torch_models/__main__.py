"""Entry point of ``python -m torch_models``."""
import sys

from .cli import main

sys.exit(main())
