"""The hand in the filter: ``kf_hand`` and ``kf_hand_joint`` (:mod:`.filter`), one module per part of the model, and
the checks of the method's assumptions on a recording (:mod:`.checks`).

A real hand turns the board about a pivot away from the sensor and sways and trembles: the lever arm's
acceleration and a coloured external acceleration are filter states, after a low-pass below the tremor.  Read from
the bottom: :mod:`.lowpass` (the tremor pre-filter), :mod:`.lever` (the lever arm's regressor), :mod:`.sway` (the
external acceleration's model and σ under the data's spectrum), :mod:`.thermal` (temperature), :mod:`.priors` (the
extra blocks' priors), :mod:`.reports` (what the result states besides the parameters), :mod:`.checks`,
:mod:`.params` (:class:`~calib.session.hand.params.HandParams`, the method's parameters) and :mod:`.filter` (the
method).
"""
