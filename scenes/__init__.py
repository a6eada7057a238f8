"""Layer 0 of the toolkit: scene description, Mitsuba build, object folders, CLI machinery (ARCHITECTURE.md).

Importing it in a Python without the toolkit's packages raises `scenes.cli.errors.MissingDependencyError` (one
line: what is missing and the fix; `scenes.dependencies`); it never exits the process."""
from scenes.dependencies import require_environment

require_environment()
