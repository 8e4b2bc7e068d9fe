"""Sparse linear algebra shared by the two models: one CHOLMOD wrapper, the projection's envelope
factorisations with bordering, and AMG-preconditioned conjugate gradients."""
