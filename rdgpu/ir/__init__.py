"""Equations as data: the expression tree and its parser (py-pde's spelling), the linear
spatial part, and the generated names that can never collide with a user's
(``equations.py``, ``names.py``); a fused pass as data (``program.py``: ``Program``), the one
stencil table per domain kind and the stencil walk the printers share (``stencils.py``), a
domain as the host sees it (``layout.py``) and the NumPy semantics of a Program
(``reference.py``)."""
