"""photometric package."""
