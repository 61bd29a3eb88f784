"""The ``stridelab`` command line: the one module that wires the layers together
(estimators <- warehouse <- pipeline <- reports / validation <- stridelab; dashboard beside reports)."""
