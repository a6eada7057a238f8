"""Capture diagnosis from the images alone, before any model runs: light variation, the automatic mask, the capture
warnings (usable) and camera motion between the photos (camera_motion)."""
