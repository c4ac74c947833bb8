"""Finite elements: quadrature rules, plane-stress quads and zero-thickness line interfaces."""
