"""Reports for a person: the study's tables and figures, pictures of plans, scenes and runs
(drawn after all jitted work, from scored tables; no ground truth of their own)."""
