"""augment.autows."""
