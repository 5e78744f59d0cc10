"""Capsule benchmark (the 2012 implementation's measurement case).

Run: ``python benchmarks/speed/bench_capsule.py`` (same as ``musclewrap bench capsule``).
"""

import sys

from musclewrap.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "capsule", *sys.argv[1:]]))
