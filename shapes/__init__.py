"""Facet shape models, materials, primitives, mesh IO and the shape library."""
