"""dexaug.pipeline."""
