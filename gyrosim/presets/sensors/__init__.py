"""Built-in sensor presets (TOML, datasheet units), loaded by name with :func:`gyrosim.sensor_model.load_sensor`."""
