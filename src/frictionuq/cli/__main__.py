"""`python -m frictionuq.cli`"""
import sys

from . import main

sys.exit(main())
