"""The hand in the filter: ``kf_hand`` and ``kf_hand_joint`` (:mod:`.filter`), and the checks of their
assumptions on a recording (:mod:`.checks`).

A real hand turns the board about a pivot away from the sensor and sways and trembles: the lever arm's
acceleration and a coloured external acceleration are filter states, after a low-pass below the tremor.
"""
