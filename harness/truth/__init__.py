"""Truth and scoring: what is right for a scene, and how far a technique's V is from it.

- ``reference``: the Mitsuba reference, exact hard-shadow visibility averaged over each pixel's
  area (and the direct-lit image where the scene asks for it), cached on disk by content hash.
  Start at :func:`harness.truth.reference.compute_reference`.
- ``metrics``: pure functions of V against V_ref (error, edge band, acne, leak, edge floor,
  SSIM, PSNR, FLIP, flicker), arrays first and options as keywords; their version enters every
  run id.

It lies below the technique contract (a technique may score itself, as the warps do) and above
the scene, whose triangles the reference traces.
"""
