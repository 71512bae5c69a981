"""The hand-held session: gyro and accelerometer calibration from hand rotation, bottom up like the paper.

Zhou et al. 2020, *A Novel MEMS Gyroscope In-Self Calibration Approach* (Sensors 20:5430), extended by the
accelerometer and the hand.  Read it from the bottom (each module imports only those above it in this list):

- :mod:`.model`: the error model's equations, the filter's state layout, its configuration and priors;
- :mod:`.kernel`: the filter compiled (numba) and batched — the one every method runs;
- :mod:`.reference`: the same filter written for reading, one sample at a time (tested equal to the kernel);
- :mod:`.rest`, :mod:`.rest_bias`, :mod:`.noiselevels`, :mod:`.gravityfit`, :mod:`.observability`,
  :mod:`.consistency`, :mod:`.spectral`: what a session's rests give (the static bias, the noise levels, the
  |f| = g accelerometer fit), what the motion determines, and is σ honest;
- :mod:`.prepare`: a recording prepared for a filter (checks, rests, noise, the |f| = g fit, P₀) — shared by both
  methods; :mod:`.drift`: the gyro bias's drift between the rests — shared too;
- :mod:`.hand`: the hand-aware method ``kf_hand`` (lever arm, sway, temperature, …), one module per part;
- :mod:`.bounds`: the Cramér–Rao bounds, ideal and hand-aware;
- :mod:`.crosscheck`: a hand-blind result against the hand-aware one (above both methods);
- :mod:`.paper`: the paper family — ``calibrate()`` (``kf_session``, ``iterated_session``) and the paper filter's
  variants (:class:`~calib.session.paper.PaperParams`);
- :mod:`.validation`, :mod:`.residuals`, :mod:`.coach`: attitude validation, checks on measured data, and
  what the hand cost the session;
- :mod:`.registry`: the estimators by name, the one place that knows names.
"""
