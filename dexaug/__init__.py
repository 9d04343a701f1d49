"""Command-line entry point of dexaug (``dexaug --help``); the work lives in sim/, augment/ and
teleop/."""
