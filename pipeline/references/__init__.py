"""Independent references: solutions that share no code with pipeline.model or pipeline.engines."""
