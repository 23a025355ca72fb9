"""Runs that compute with the library packages and write result folders."""
