"""The study: the pipeline, the derived experiments and the report."""
