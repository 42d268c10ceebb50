"""Conformance suite for XA-C1 controllers (pytest plugin and checks)."""
