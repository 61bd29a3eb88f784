"""``python -m stridelab`` = the ``stridelab`` command."""
from stridelab.cli import main

if __name__ == "__main__":
    main()
