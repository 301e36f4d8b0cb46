"""Distractors, which are not in the 3D model: meshes of furniture-like clutter and people
(``meshes``, built from ``primitives``), their placement on a floor map (``placement``), the
walking people of a flight (``crowd``) and the presets that say how many (``presets``)."""
