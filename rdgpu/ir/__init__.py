"""Equations as data: the expression tree and its parser (py-pde's spelling), the linear
spatial part, and the generated names that can never collide with a user's."""
