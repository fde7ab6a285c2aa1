"""The one exception type that means "the user asked for something we cannot do"."""


class UserError(ValueError):
    """Bad input from a user: the message is one line naming the problem and the fix.

    The CLI prints it without a traceback and exits with code 2.
    """
