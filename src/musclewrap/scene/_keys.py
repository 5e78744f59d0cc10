"""What a scene file may say and what a run writes: the tables the reader and the docs share.

`SCENE_KEYS` lists every key of every table of a scene file, with what it means; the reader
(`load_scene`) refuses any other, and the documentation's scene reference is generated from
it, so neither can drift from the other. `OUTPUT_COLUMNS` does the same for the columns of the
CSV files a run writes (their order is the files').
"""

from __future__ import annotations

__all__ = ["OUTPUT_COLUMNS", "SCENE_KEYS"]

#: table (``""``: the top level; ``muscles.NAME`` one per muscle) -> key -> meaning
SCENE_KEYS: dict[str, dict[str, str]] = {
    "": {
        "name": "Title of the plots (default: the file's name).",
        "units": "Table: the meshes' and the model's length units.",
        "model": "Table: the OpenSim model and motion that drive the scene.",
        "lines": "Table: action lines from a CSV file instead of a model.",
        "output": "Table: the pictures and plots of a run.",
        "muscles": "Tables, one per muscle: ``[muscles.NAME]``.",
        "bones": "Tables, one per bone: ``[bones.NAME]``.",
        "cache_dir": "Where preparations are cached (default ``~/.cache/musclewrap`` or "
        "``$MUSCLEWRAP_CACHE``; ``--cache-dir`` overrides it).",
        "registration": "Table: meshes of another subject, placed on the model by landmarks.",
        "collisions": "Table: contact with the bones and between the muscles.",
        "fibres": "Table: fibres in every muscle, their lengths and moment arms.",
        "line_window": "Each sample of an action line is the line's mean over this many sample "
        "spacings either side (default 0: the line's point); 1 removes the steps a path's "
        "point sliding past a sample gives the fibres' moment arms (docs: Fibres).",
    },
    "units": {
        "mesh": "Length unit of the mesh files: ``m``, ``cm`` or ``mm``.",
        "model": "Length unit of the model: ``m``, ``cm`` or ``mm`` (converted to the meshes').",
    },
    "model": {
        "osim": "The OpenSim model (``.osim``), relative to the scene file.",
        "motion": "A motion (``.mot`` / ``.sto``) or a list of them (one output folder each).",
        "rest_pose": "The pose the meshes were segmented in: coordinate -> value (degrees for "
        "rotations); the others at their defaults.",
        "angle_unit": "``header`` (the motion's ``inDegrees``; guessed and reported if "
        "absent, the default), ``deg`` or ``rad``.",
        "coordinates": "The motion's columns that drive the model (default: every one that "
        "names a coordinate).",
        "output_frame": "Frame of every output: a body's name or ``ground`` (the default).",
        "mesh_frame": "Frame the meshes are given in: ``body`` (each in its body's frame at "
        "the rest pose, the default), ``ground``, a body's name, or ``registration``.",
        "geometry": "The folder of the model's mesh files, for bones taken from the model "
        "(``[bones.NAME] model``; default: the model's folder, its ``Geometry`` folder, or the "
        "``Geometry`` folder beside it).",
    },
    "lines": {
        "csv": "Action lines per frame: header ``frame,time,muscle,line,point,x,y,z``, mesh "
        "units; a line named ``reference`` with one point gives the reference point.",
        "rest_frame": "The frame of the CSV file that is the rest pose (default 0).",
        "bodies": "The bodies' poses per frame, for bones that move: header "
        "``frame,time,body,r11,r12,r13,r21,r22,r23,r31,r32,r33,x,y,z`` (the rotation row by "
        "row and the translation that take the body's frame into the scene's, mesh units); a "
        "bone names its body with ``body``.",
    },
    "output": {
        "bone_display_faces": "Faces of the bones' display copies (default 10000; for "
        "display only).",
        "paper_frames": "Frames on which the paper's eq. 11 also runs, for the comparison "
        "plots (default 2, plus the worst).",
        "gif": "Draw ``scene.gif`` and its middle picture ``scene.png`` (default true).",
        "gif_every": "Draw every n-th frame (default 1).",
        "image_size": "Pictures' size in pixels, ``[width, height]`` (default [800, 600]).",
        "view": "The pictures' camera turned from the side view, ``[azimuth, elevation]`` in "
        "degrees (default [0, 0]: along the thinnest extent of the muscles' box through the "
        "motion, its longest one up).",
        "colour": "How the pictures colour the muscles: ``muscle`` (one colour each, the "
        "default) or ``stretch`` (the surface's local stretch against the rest mesh, the "
        "files' ``stretch`` array).",
    },
    "muscles.NAME": {
        "mesh": "The muscle's surface mesh (STL, VTK, VTP, PLY or OBJ).",
        "paths": "The model's muscles whose paths are its action lines (one muscle may have "
        "several).",
        "body": "The body that carries the mesh: the muscle is deformed in its frame.",
        "reference": "With line CSV files: a bone whose centroid fixes the twist about the "
        "lines (not used with a model).",
        "cage_size": "Vertices of the cage (default 300).",
        "cage_coarsening": "How the cage is remeshed: ``uniform`` (equal-area clustering, "
        "the default) or ``quadric``.",
        "method": "Solver: ``sqp`` (the default), ``exact`` or ``paper`` (eq. 11).",
        "max_iterations": "Iteration limit of the solver (default per method).",
        "repair": "Repair a damaged mesh (default true); false refuses it instead.",
        "frame": "Frame this mesh is given in, overriding ``[model] mesh_frame``.",
        "bones": "The bones it is kept out of (default: all of the scene's).",
        "fibre_origin": "The fibres' origin area: vertex indices of the mesh file, or "
        "landmark points (mesh coordinates; the surface within ``landmark_radius``); "
        "default: as ``[fibres] attachments`` says.",
        "fibre_insertion": "The fibres' insertion area, as ``fibre_origin``.",
    },
    "bones.NAME": {
        "mesh": "The bone's surface mesh.",
        "model": "Instead of ``mesh``: the model's own mesh of this body, by its file name "
        "(a ``<mesh_file>`` of the body's ``<attached_geometry>`` in the ``.osim``), placed and "
        "scaled as the model does (its ``scale_factors``, in the body's frame).",
        "body": "The body that carries it.",
        "frame": "Frame this mesh is given in, overriding ``[model] mesh_frame``.",
        "fit": "``'shaft'``: a long bone (a model's, on another subject's muscles) fitted to "
        "the muscles at rest, its cross-sections moved across its axis where the muscles "
        "leave room (`musclewrap.model.fit_shaft`); held where the body's other bones and "
        "its joints' centres are. Default: as placed.",
    },
    "registration": {
        "axes": "Mesh axes that become the model's x, y, z, e.g. ``['y', 'z', 'x']`` "
        "(``-x`` flips one); optional with three or more landmarks.",
        "landmark": "Two or more ``[[registration.landmark]]`` tables.",
    },
    "registration.landmark": {
        "name": "The landmark's name (in the run's notes).",
        "mesh": "The mesh the landmark is found on.",
        "fit": "``sphere`` (the centre of a fitted sphere), ``centroid`` (the surface's "
        "area-weighted centroid, the default), or on a whole femur's mesh ``femoral_head`` "
        "(its head's centre: the hip) or ``femur_distal`` (its condyles' centroid: the knee).",
        "body": "The landmark goes onto this body's origin at the rest pose ...",
        "point": "... or onto this point of the body (model units).",
    },
    "collisions": {
        "enabled": "Keep the muscles out of the bones (default: on whenever the scene has bones).",
        "margin": "Distance every muscle vertex keeps from every bone (mesh units, default 0).",
        "rest_overlap": "``resolve`` (the default) or ``keep``: bones: only new penetration "
        "is prevented; muscles: left as segmented.",
        "muscles": "Keep the muscles out of each other (default true with two or more).",
        "pairs": "Only these pairs of muscles are kept apart (default: every pair).",
        "together": "Muscles that overlap in a round take one step of their cages together "
        "(each overlap one condition on both), not a step each with its share: muscles held "
        "by a bone meet where their energies say (default false; docs: Contact).",
    },
    "fibres": {
        "count": "Fibres per muscle (default 100).",
        "points": "Points per fibre (default 15).",
        "moment_arms": "Coordinates whose moment arms are computed (default: none).",
        "step": "Half-width of the central difference: degrees for a rotation, mm for a "
        "translation (default 1).",
        "voxels": "Cells of the grid the fibre field is solved on (default 60000).",
        "moment_arm_contact": "Deform the poses either side of a frame with the bones' "
        "contact (default false).",
        "landmark_radius": "Radius of an attachment area given as landmark points (mesh "
        "units, default 10).",
        "attachments": "Where the fibres attach where a muscle gives no areas: ``bones`` (where "
        "it lies on a bone of its origin's or insertion's body near its paths' ends, the "
        "default; its end cap where the scene has no such bone) or ``ends`` (its end caps "
        "along its lines; docs/fibres.md).",
        "attached": "Hold each muscle's attachment areas to its paths' first and last points "
        "through the motion, turning with their bodies and the paths' end segments, for its "
        "surface and fibres (default true; docs/fibres.md).",
    },
}

#: CSV file -> column -> meaning (in the files' order)
OUTPUT_COLUMNS: dict[str, dict[str, str]] = {
    "report.csv": {
        "frame": "The motion's row.",
        "time": "The motion's time (s).",
        "muscle": "The muscle's name in the scene.",
        "iterations": "Solver iterations for the frame.",
        "converged": "Whether the solve converged (the exit status is 3 when one did not).",
        "relative_volume_error": "Volume of the written mesh over the rest volume, minus 1.",
        "skeleton_fit_mean": "Mean distance between the deformed skeleton samples and the "
        "action lines (mesh units).",
        "seconds": "Time of the frame's solve.",
        "shape_change_max": "Largest change of a vertex's position relative to its "
        "neighbours, in mean edge lengths (a crease or spike shows here).",
        "penetration_share": "Share of the muscle's vertices inside a bone, on the written mesh.",
        "penetration_depth_max": "Deepest muscle vertex inside a bone (mesh units).",
        "bone_inside_depth_max": "Deepest bone vertex inside the muscle (mesh units; found "
        "by the contact, NaN without it).",
        "muscle_overlap_max": "Deepest vertex of this muscle inside another muscle (mesh "
        "units; NaN without muscle contact).",
        "muscle_rounds": "Rounds that took the muscles kept apart out of each other in this "
        "frame (the same for all of them; 0: apart after their own solves, or muscles not "
        "kept apart).",
        "contact_vertices": "Vertices the contact moved.",
        "penetration_depth_before": "Deepest vertex inside a bone before the contact (mesh units).",
        "line_inside_depth_max": "Deepest point of the muscle's own action lines inside a "
        "bone (mesh units): where the model's path itself passes through a bone.",
        "skeleton_fit_free": "Mean distance between the deformed skeleton samples and the "
        "action lines over the samples whose place on the lines lies outside every bone of "
        "the muscle (mesh units): the fit where the lines can be followed.",
        "lines_conflict_max": "Largest distance between a deformed skeleton sample and its "
        "line where its place on the line lies inside a bone (mesh units; 0: none): how far "
        "the surface, kept out of the bone, had to leave its line.",
        "reason": "Why a frame did not converge, or how it converged.",
    },
    "fibres.csv": {
        "frame": "The motion's row.",
        "time": "The motion's time (s).",
        "muscle": "The muscle's name.",
        "fibre": "The fibre's index in the muscle.",
        "share": "The fibre's share of the muscle's cross-section where it is widest (the "
        "cells of that level of the fibres' field nearer its seed than any other's; the "
        "muscle's shares sum to 1): a weight for it.",
        "area": "The fibre's cross-section: its share of the muscle's volume over its mean "
        "fibre length at rest (mesh units squared; the physiological cross-section without "
        "pennation).",
        "length": "The fibre's length in this frame (mesh units).",
        "coordinate": "The coordinate of the moment arm (empty without moment arms).",
        "coordinate_value": "That coordinate's value in this frame (degrees or mm).",
        "moment_arm": "The fibre's moment arm about it, ``-dL/dq`` (mesh units).",
    },
    "moment_arms.csv": {
        "frame": "The motion's row.",
        "time": "The motion's time (s).",
        "muscle": "The muscle's name.",
        "coordinate": "The coordinate.",
        "coordinate_value": "Its value in this frame (degrees or mm).",
        "fibre_min": "The smallest of the fibres' moment arms.",
        "fibre_mean": "Their mean.",
        "fibre_max": "The largest.",
        "line_moment_arm": "The action lines' own moment arm (the same difference on the "
        "lines' length).",
        "opensim_moment_arm": "OpenSim's ``computeMomentArm`` of the muscle's path(s).",
    },
}
