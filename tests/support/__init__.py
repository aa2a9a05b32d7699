"""Test support: FMU hosts (fmpy, a plain C host, libcosim) that tests run FMUs in."""
