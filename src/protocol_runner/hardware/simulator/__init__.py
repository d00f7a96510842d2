"""hardware simulator package."""
