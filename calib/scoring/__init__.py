"""The score floor: estimators against the truth and against each other.

:mod:`.montecarlo` (the calibration against the Cramér–Rao bound), :mod:`.instruments_mc` (north-finding
and the tilt test over many drawn devices), :mod:`.speed` and :mod:`.mag_speed` (wall time as ratios
against a baseline in the same run).  Nothing below this folder imports it.
"""
