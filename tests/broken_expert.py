"""An expert module that fails on import, as a user's module with a typo would."""

raise RuntimeError("this module does not import")
