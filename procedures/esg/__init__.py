"""Strapdown ESG readout laboratory (report 004): data reduction and readout study.

Pure functions, no instrument I/O (docs/esg.md, "Reduction and study"):

* ``mechanization``  nominal great-circle mechanization (eqs. 4-10), equal-ratio points
* ``chebyshev_fit``  weighted Chebyshev least squares of the deviation (eqs. 11-12)
* ``drift``          drift correction by linear interpolation in time (step 13)
* ``readout``        spin axis from pickoff cosines, two/three-pickoff modes, eqs. (2), (3)
* ``strategy``       error amplification of line-edge uncertainty (Figure 2) and its plot

The package's other modules (mounting geometry, acquisition) belong to the procedure.
"""
