"""Shipped kit descriptions (YAML); a package so the files install with it."""
