"""The association half: ``Problem``, ``Association`` validation and the compatibility math."""
