"""Errors raised on bad user input.

Every check that guards a public function raises :class:`InputError` with a message that
names the problem and the fix. The command line prints such messages without a traceback.
"""


class InputError(ValueError):
    """Bad input from a user: the message says what is wrong and how to fix it."""


class SimulationError(RuntimeError):
    """The simulation reached a state it must not carry on from (a particle in a wall)."""
