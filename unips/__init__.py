"""Universal photometric stereo: loaders, preprocessing, models, training, prediction, evaluation."""
import scenes  # noqa: F401  (a clear error, not a traceback, outside the toolkit's environment)
