"""Readers of public robot data sets (one module per format) and their download."""
