"""Shipped behaviours (registered by name for the command line)."""
