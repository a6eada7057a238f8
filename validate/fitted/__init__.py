"""The fitted mode of the check: without a scene file, light and reflectance fitted to the images around a normal
map (verdict, fit, fit_report), and refinement of the map (refinement, regulariser, rotation_search)."""
