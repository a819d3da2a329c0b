"""The command line's logic as plain keyword-only functions, one module per verb, each returning
a typed result (the ``cli`` package only parses and prints): :mod:`.run`, :mod:`.report`,
:mod:`.reproduce`, :mod:`.analyze`, :mod:`.bench`, :mod:`.compare`, :mod:`.sweep`, :mod:`.replay`,
:mod:`.repair`, and :mod:`.controller_replay` (recorded inputs fed again through a controller,
for timing).

Every engine writes a bag through the same recorder code, and every figure printed for a run is
computed from that bag, so ``report`` on the bag always agrees with what ``run`` printed.
"""

__all__ = [
    "analyze",
    "bench",
    "compare",
    "controller_replay",
    "repair",
    "replay",
    "report",
    "reproduce",
    "run",
    "sweep",
]
