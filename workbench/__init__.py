"""Command line, end-to-end demo, reports and batch runs of the surface-reconstruction workbench."""
