"""pythonfmu shells: one Fmi2Slave per file, loaded by file by the build.

Each imports its physics cores by bare module name (they travel in the FMU).
"""
