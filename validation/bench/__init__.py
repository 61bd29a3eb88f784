"""Benchmarks: ``stridelab bench NAME``. Every module here that defines a click command named
``command`` is registered automatically as a subcommand of ``stridelab bench``."""
