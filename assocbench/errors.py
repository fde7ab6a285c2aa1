"""The one exception type that means "the user asked for something we cannot do"."""


class UserError(ValueError):
    """Bad input from a user: a one-line message naming the problem and the fix; the CLI prints it
    without a traceback and exits 2.
    """
