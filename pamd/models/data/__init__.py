"""The samples every model kind trains on, whatever the kind: recorded runs read,
the training pairs extracted, split and checked."""
