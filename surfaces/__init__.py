"""Shared surface model: bicubic Bezier patches and everything built on them."""
