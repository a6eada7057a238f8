"""The command-line machinery of every CLI: options from config dataclasses (tyro), one-line errors, output
folders and --overwrite, machine limits, progress."""
