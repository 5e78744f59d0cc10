"""Contact: bones, other muscles, finding where a muscle meets them, the finish.

The one room that knows what an obstacle is: `Obstacle` (a closed surface with a
signed-distance grid and exact closest points) placed in a pose (`Placed`); which
vertices can be near it (`Near`); the contacts of a pose stated as linear conditions
on the fine vertices (`contact_candidates`); the fine finish that takes the last
vertices out, volume-exact (`push_out`); and the rest pose's overlap, settled once
(`rest_push_out`, `anchors_at_rest`). Muscles against each other: where each faces
the other at rest (`facing_faces`, `facing_pairs`), the vertices of each inside another
with their way out (`overlaps`), each side's share (`meetings`, `push_apart`), the
deepest (`overlap_depths`), how far each vertex is from the muscles beside it
(`muscle_gaps`, for pictures), and segmented muscles that overlap at rest taken apart
once (`apart_at_rest`). The solver solves the conditions it is given.
"""

from ._find import contact_candidates
from ._finish import (
    ContactReport,
    longest_pushes,
    nudge,
    press,
    push_out,
    rings,
    triangle_pushes,
    unfold,
    vertex_faces,
)
from ._gaps import FacesWithin, muscle_gaps
from ._inside import Inside, bone_vertices_inside, line_inside_depth
from ._muscles import (
    Meeting,
    Overlap,
    RestPair,
    apart_at_rest,
    distance_outside,
    every_pair,
    facing_faces,
    facing_pairs,
    meetings,
    overlap_depths,
    overlaps,
    push_apart,
)
from ._near import Near
from ._obstacle import Obstacle, bone_surface, pseudo_normals, signed_from_closest
from ._placed import Placed, as_placed
from ._rest import anchors_at_rest, attachment_patches, kept_allowance, rest_push_out
from ._sides import SideReference, on_their_side, passed_through

__all__ = [
    "ContactReport",
    "FacesWithin",
    "Inside",
    "Meeting",
    "Near",
    "Obstacle",
    "Overlap",
    "Placed",
    "RestPair",
    "SideReference",
    "anchors_at_rest",
    "apart_at_rest",
    "as_placed",
    "attachment_patches",
    "bone_surface",
    "bone_vertices_inside",
    "contact_candidates",
    "distance_outside",
    "every_pair",
    "facing_faces",
    "facing_pairs",
    "kept_allowance",
    "line_inside_depth",
    "longest_pushes",
    "meetings",
    "muscle_gaps",
    "nudge",
    "on_their_side",
    "overlap_depths",
    "overlaps",
    "passed_through",
    "press",
    "pseudo_normals",
    "push_apart",
    "push_out",
    "rest_push_out",
    "rings",
    "signed_from_closest",
    "triangle_pushes",
    "unfold",
    "vertex_faces",
]
