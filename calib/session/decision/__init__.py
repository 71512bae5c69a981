"""What a session's result applies and whether it is ``ok``: the decision layer above every session method.

* :mod:`~calib.session.decision.prior`: the prior (a maker-calibrated sensor, or a previous calibration) and
  which parameters this recording determines against it;
* :mod:`~calib.session.decision.motion`: what the motion is (a hand turning the device, a path, taps, rest);
* :mod:`~calib.session.decision.heldout`: the held-out check (calibrate on one half, predict the other);
* :mod:`~calib.session.decision.decide`: the three together, called by :func:`calib.session.run.run_session`.
"""
