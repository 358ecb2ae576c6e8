"""The live engine: what the sources deliver, run through the same analysis core as the batch commands."""
