"""The object folder on disk: its format, its pixel files, the readers of every folder layout, and its WebDataset
shards."""
