"""Terminal tables: analysis results as Rich tables, and their JSON forms."""
