"""Shipped study specs (``scanamp study NAME``)."""
