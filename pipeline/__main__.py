"""``python -m stridelab.pipeline`` = ``python -m stridelab`` (kept for scripts written before the CLI moved to the top-level
``stridelab`` package). The one module under ``pipeline/`` allowed to import upward: it is an entry point, not
library code, and nothing imports it (tests/test_layers.py lists it as the exception)."""
from stridelab.cli import main

if __name__ == "__main__":
    main()
