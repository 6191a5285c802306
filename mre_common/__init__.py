"""Dependency-free helpers shared by both layers (``components`` and ``orchestration``).

Standard library only, and nothing of this project is imported here, so any module may use it:

* :mod:`mre_common.atomic_files`: write a file whole or not at all (temporary file, then rename).
* :mod:`mre_common.c_compile`: compile a C file into a shared library, cached by content.
* :mod:`mre_common.folder_claim`: claim an output folder with an exclusively created marker file.
* :mod:`mre_common.guard`: the command-line tools' exit codes, one-line errors and crash logs.
* :mod:`mre_common.hashing`: the SHA-256 of a file (chunked; optionally cached per file version).
"""
