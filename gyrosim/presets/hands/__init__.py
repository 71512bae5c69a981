"""Built-in hand presets (TOML) — ``ideal``, ``steady``, ``typical``, ``shaky`` — loaded by name with
:func:`gyrosim.hand.load_hand`."""
