"""augment.geometry."""
