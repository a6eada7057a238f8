import scenes  # noqa: F401  (a clear error, not a traceback, outside the toolkit's environment)
