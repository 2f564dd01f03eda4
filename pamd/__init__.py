"""pamd: the controller daemon for pneumatic artificial muscle test beds."""

__version__ = "0.1.0"
