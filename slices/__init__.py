"""CT contour stacks and RT structure sets to one interpolating surface (seed 000).

Modules
-------
io
    Readers: RTSTRUCT (``list_rois``, ``read_rtstruct``), CT series, mask stacks,
    contour JSON; ``load`` picks by input.
control_points
    Contour checks and orientation, the seed's control-point parameters
    (rays, support points, turning points, chord length; eqs. 1-5).
surface
    Slice curves on a common lattice, side surfaces (parabolic blending,
    Coons, B-spline: the ``METHODS`` table), fast patch integrals and tessellation.
caps
    End caps (none, flat, half, dome).
chaining
    Holes by containment, bodies by overlap, the planning-system slab volume.
reference
    The smoothing B-spline comparison (seed 000, ref. [5]).
pipeline
    ``reconstruct_contours`` (in memory) and ``reconstruct`` (files in, files out).
"""
