"""Interoperability: SSP 1.0 packages and running our system in libcosim."""
