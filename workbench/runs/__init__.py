"""Runs: a library pipeline's result written into an output folder, as the command line,
batch jobs and the demo need it (the libraries compute, these modules write)."""
