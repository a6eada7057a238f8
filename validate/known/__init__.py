"""The known-scene mode of the check: each image's recorded scene re-rendered with the judged normals swapped in
(projection, normal_bsdf, rerender_passes, rerender_report)."""
