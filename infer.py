"""dcfvision inference command line: ``python infer.py --help`` lists the commands (``cli/``, one module each)."""

import sys

from cli import main

if __name__ == "__main__":
    sys.exit(main())
