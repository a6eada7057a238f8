"""From a normal map to a surface: the one integrator of the toolkit (`integrate`), its checked inputs
(`inputs`) and its mesh (`mesh`). `orchestrate.surface` is its command; the fitted check builds its geometry
with it."""
