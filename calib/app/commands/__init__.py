"""The ``calib`` commands, one module per group: each command parses its options, makes one library call,
prints, saves, and returns its exit code (:data:`gyrosim.cli.EXIT_CODES`).

- :mod:`.session`: ``run``, ``apply``, ``export``, ``inspect``, ``demo`` (the hand-held calibration);
- :mod:`.noise`: ``allan``, ``noise``, ``plan``;
- :mod:`.temperature`: ``temperature``, ``ratetable``;
- :mod:`.closeloop`: ``closeloop``;
- :mod:`.mag`: ``mag``;
- :mod:`.instruments`: ``northfind``, ``tilt``;
- :mod:`.lab`: ``calib lab …``, the research and benchmark commands;
- :mod:`.common`: what they share (the input options, the input boundary, output checks).
"""
