"""Alignment computations of report 000 (Part I Section 3, Part III)."""
