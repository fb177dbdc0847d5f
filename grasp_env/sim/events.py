"""What happens along a move, as codes: the events a state reports and the checks that find
them.

An event log is a list of ``(kind, s, keys)``: the code, the path parameter where it
happened and the contacts involved (an array (k, 4)).
"""

from __future__ import annotations

#: Events of a move (:class:`grasp_env.core.state.Event` kinds, in :data:`NAMES`' order).
NEW_CONTACT, EDGE_TO_TIP, TIP_TO_EDGE, LOST_CONTACT, FALL_START, FALL_END, JAM = range(7)
#: Checks that are not events themselves: a hand body overlapping the object (edges about to
#: cross: a new contact), the residual of the active set's equilibrium, nothing checked.
OVERLAP, EQUILIBRIUM, NO_CHECK = 7, 8, 9

NAMES = (
    "new_contact", "edge_to_tip", "tip_to_edge", "lost_contact", "fall_start", "fall_end",
    "jam",
)  # fmt: skip
