"""Closed-form reference solutions used to design and verify the virtual tests.

:mod:`podkrig.analytical.flat_jack`: stresses and displacements around a pressurised elliptical
hole and a pressurised slot in an infinite plate, the displacement-discontinuity method for several
slots, and the classical flat-jack evaluations (ASTM C1196/C1197, RILEM MDT.D.4/D.5).
"""
