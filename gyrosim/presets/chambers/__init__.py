"""Built-in thermal-chamber profiles (TOML), loaded by name with :func:`gyrosim.chamber.load_chamber`."""
