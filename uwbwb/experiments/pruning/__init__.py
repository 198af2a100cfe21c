"""Notebook 02: trajectory estimation by NLS with pruning heuristics (Zupanec et al.).

``study`` runs the synthetic comparisons; ``scoring`` holds the estimator names, the one scorer of a segment
(``score_segment``, which every comparison calls) and the per-estimator table;
``real`` runs the LIAS static poses and dynamic pieces, ``sections`` the notebook's LIAS sections in one call each;
``figures`` draws them; ``panels`` backs the notebook's widgets; ``headlines``
declares the summary rows and the checks; ``exercises`` checks the notebook's exercises; ``verdicts`` decides the
comparison with the paper by intervals (``verdict_table``, ``wins_table``).
"""

from . import exercises, figures, headlines, panels, real, scoring, sections, study, verdicts

__all__ = ["exercises", "figures", "headlines", "panels", "real", "scoring", "sections", "study", "verdicts"]
