"""Shared FMU plumbing bundled into every FMU: slave base, XML post-processing, state, loader."""
