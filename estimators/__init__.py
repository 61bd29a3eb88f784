"""Pure numerical algorithms of StrideLab: arrays in, arrays/dataclasses out, no I/O.

Conventions (DESIGN.md, tested in tests/estimators/test_conventions.py):
quaternions Hamilton scalar-first ``[w, x, y, z]``; ``q`` rotates sensor-frame vectors into the
earth frame (``v_E = q ⊗ v_S ⊗ q*``); earth frame ENU (z up); accelerometer m/s² (specific force,
+9.81 on the up axis at rest), gyroscope rad/s, magnetometer µT, time in float seconds.
"""

from stridelab.estimators import _numba_cache  # noqa: F401,E402 - the installation's shared numba cache, before any kernel
