"""The project's one error type for bad input: the entry points print it as one line, exit 2.

It lives in the learner, the lowest floor that raises it, so `viz` and `sim` share it without
importing upwards."""


class InputError(ValueError):
    """Bad user input (scenario, family TOML, knob value, data file, option).

    The message names the input and what is wrong; it is shown to the user as is.
    """
