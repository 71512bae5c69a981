"""Built-in rotation schedules (TOML), loaded by name with :func:`gyrosim.schedule.load_schedule`."""
