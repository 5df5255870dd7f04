"""impact_fenics: explicit transient dynamics with contact on axisymmetric solids."""
import os as _os

# numba colours its messages with colorama when that is installed, and colorama then
# writes a terminal reset code at exit: a stray escape code on the console of every run
_os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")
