"""Passive decoder of XA-C1 traffic between a host and a controller."""
