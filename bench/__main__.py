"""python -m bench: run time against error of the pipeline and of CalculiX (bench.run)."""
import sys

from bench.run import main

if __name__ == "__main__":
    sys.exit(main())
