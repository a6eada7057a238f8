"""Universal photometric stereo: loaders, preprocessing, models, training, prediction, evaluation."""
