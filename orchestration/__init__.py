"""mre-cosim: the engine (master/), studies, interop, the Python API (api.py) and the command-line tools."""
