"""Worked examples of gyrosim and calib used as libraries; a package, so that a campaign can import
``examples.own_estimator:lowpassed_acc_kf`` by its path."""
