"""Seeded appearance randomization of a scene: textures (``textures.sample_textures``, drawn
by ``floors``, ``walls`` and ``openings`` with ``drawing``'s primitives and ``choices``'
styles), ceiling lights (``lights``) and materials (``materials``)."""
