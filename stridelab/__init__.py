"""StrideLab: wearable-IMU gait and daily-activity pipeline.

From Python (``stridelab.api``)::

    import stridelab
    wh = stridelab.open("stridelab-home")        # newest snapshot of the warehouse, read-only
    wh.strides(participant="P003")                # pandas DataFrame
    rec = stridelab.read_recording("walk.mcap")   # arrays with units

The command line is :mod:`stridelab.cli` (the one module that wires the layers together:
estimators <- warehouse <- pipeline <- reports / validation <- stridelab; dashboard beside reports).
Importing the package has no side effects and imports nothing heavy.
"""
from stridelab.api import TableMissing, Warehouse, open, read_recording

__all__ = ["open", "read_recording", "Warehouse", "TableMissing"]
