"""The robot's side: the streaming localizer, many recordings at once, a folder being
written, and what a decision means for a person (status lines, decisions records)."""
