"""The phase machine's discrete codes, one encoding for every layer: the modes and the kinds of event.

The machine, compiled or not, reads these ints (numba compiles ints, not enums); physics.Mode and
solvers.result.EventKind are their named faces for users, built from them (tests/test_codes.py pins it).
"""

# The discrete phase, held between events. FREE: below R with no contact force (the no-pull law's free
# sub-mode, the Hunt-Crossley law's past its release speed): the flight's parabola.
FLIGHT, CONTACT, FREE = 0, 1, 2
MODE_NAMES = ("flight", "contact", "free")  # by code

# The kinds of event (an event row's (t, kind, v)): an impact starts a contact, a departure ends one; a release
# (pressed to free) and an engagement (free to pressed) switch the sub-modes below R.
IMPACT, DEPARTURE, RELEASE, ENGAGE = 0, 1, 2, 3
EVENT_KIND_NAMES = ("impact", "departure", "release", "engage")  # by code: EventKind's values
# Not an event: the phase machine's pending restart of CVODE at a step's end in the same mode (a root of CVODE's
# that the exact flow does not confirm), taken as events are (after the step's targets), no row recorded.
RESTART = -1
