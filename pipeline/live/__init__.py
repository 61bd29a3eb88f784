"""Live sessions: IMU streams -> online orientation, joint angles and gait events per sample -> a
biofeedback page in the browser, with the session recorded to recording-format MCAP as it arrives.

Modules: ``streams`` (a recording file as per-sensor arrays), ``osc`` (OSC 1.0 / x-io NGIMU parser),
``sources`` (replay and UDP sources), ``align`` (sensor clocks -> one frame grid, gaps counted),
``engine`` (the causal per-frame computation, estimators only), ``calibration`` (before the session),
``recorder`` (crash-safe streaming MCAP), ``server`` (tornado HTTP + WebSocket, static pages),
``session`` (wires them), ``command`` (``stridelab live``). User guide: docs/live.md.
"""
