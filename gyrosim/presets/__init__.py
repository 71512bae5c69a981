"""Built-in presets shipped as TOML data: sensors, hands and chamber profiles, one folder each."""
