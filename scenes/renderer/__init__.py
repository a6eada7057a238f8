"""Mitsuba: the variant, the build of a scene description into one Mitsuba scene with light slots, and the
renders (images and the ground-truth pass)."""
