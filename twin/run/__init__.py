"""The application layer: a command's work from its arguments to its files (a campaign run
in the twin or on devices, a check, a replay), over the library's packages."""
