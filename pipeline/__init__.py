import stridelab.estimators  # noqa: F401 - sets the shared numba cache dir before the format readers define kernels
