"""Shipped gesture units (BVH + JSON), a package so they install. Rebuild: python -m common.gesture.synth."""
