"""Audits of the product that are not part of it: the test over the continuum
(``path_bound``: upper bounds of a path's fit over cells of placements; ``path_certify``:
branch and bound over every heading and translation) and the audit that runs it over the
benchmark's windows (``python -m experiments.audit.certificate``)."""
