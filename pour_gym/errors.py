"""Errors raised on bad user input.

Every check that guards a public function raises :class:`InputError` with a message that
names the problem and the fix. The command line prints such messages without a traceback.
"""


class InputError(ValueError):
    """Bad input from a user: the message says what is wrong and how to fix it."""


class SimulationError(RuntimeError):
    """The simulation reached a state it must not carry on from (a particle in a wall)."""


class NoWaterError(InputError):
    """A mesh that holds no water however it is turned (no cavity to label)."""


class ClosedContainerError(InputError):
    """A container mesh with no opening at its top (a scan whose opening was capped).

    Args:
        name: the container's name or file.
        problem: what shows it is closed (:func:`pour_gym.mesh.measure.opening_problem`).
        flag: name ``--allow-closed`` in the fix (where a caller may label it anyway).
    """

    def __init__(self, name: str, problem: str, flag: bool = True):
        anyway = ", or pass --allow-closed to label it anyway" if flag else ""
        super().__init__(
            f"{name} looks closed at the top: {problem}. A container needs an opening: cut "
            f"the cap off at the rim (scans often close the opening){anyway}"
        )
        self.problem = problem
