"""The hand-held session: gyro and accelerometer calibration from hand rotation, bottom up like the paper.

Zhou et al. 2020, *A Novel MEMS Gyroscope In-Self Calibration Approach* (Sensors 20:5430), extended by the
accelerometer and the hand.  Read it from the bottom:

- :mod:`.model`: the error model, the filter's state layout, its configuration and the readable
  reference filter (filterpy);
- :mod:`.kernel`: the same filter compiled (numba) and batched, and the Cramér–Rao bound;
- :mod:`.rest`, :mod:`.rest_bias`, :mod:`.noiselevels`, :mod:`.gravityfit`: what a session's rests give
  (the static bias, the noise levels, the |f| = g accelerometer fit);
- :mod:`.paper`: the session prepared for a filter, and the paper-family method (``calibrate()``);
- :mod:`.hand`: the hand in the filter (lever arm, sway, drift) and the checks of its assumptions;
- :mod:`.consistency`, :mod:`.spectral`, :mod:`.observability`: is σ honest, and what the motion determines;
- :mod:`.validation`, :mod:`.residuals`, :mod:`.coach`: attitude validation, checks on measured data, and
  what the hand cost the session;
- :mod:`.registry`: the estimators by name, the one place that knows names.
"""
