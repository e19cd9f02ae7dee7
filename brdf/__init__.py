"""Reflectance models (BRDFs) for facet light curves; a leaf package (numpy + torch only)."""
