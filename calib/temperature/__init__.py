"""Temperature: the gyro bias against temperature, drift compensation judged on held-out cycles, rate tables.

:mod:`.bias_model` fits the bias's temperature dependence only as far as the data support it;
:mod:`.compensation` is what ``calib temperature`` runs (fit on some chamber cycles, judge on others);
:mod:`.ratetable` the bias and scale factor at each temperature point of a rate-table recording;
:mod:`.timeblocks` the block means they share.  The former module ``calib.temperature``'s names are
re-exported here.
"""

from calib.temperature.bias_model import TemperatureFit, fit_bias_temperature

__all__ = ["TemperatureFit", "fit_bias_temperature"]
