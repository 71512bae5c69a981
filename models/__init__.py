"""MJCF models, installed as the ``gyrosim.models`` package data (see pyproject.toml)."""
