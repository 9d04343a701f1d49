"""augment.fsg."""
