"""Layer 0 of the toolkit: scene description, Mitsuba build, object folders, CLI machinery (ARCHITECTURE.md)."""
from scenes.dependencies import require_environment

require_environment()
