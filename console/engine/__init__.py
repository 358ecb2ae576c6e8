"""The one pipeline every mode drives."""
