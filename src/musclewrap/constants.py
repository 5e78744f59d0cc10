"""Tolerances and defaults used across musclewrap, kept in one place.

Every numerical threshold the package relies on lives here so that tests,
benchmarks and the documentation quote the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["UNITS", "Defaults", "Tolerances", "defaults", "tol"]

#: length units accepted in a scene's ``[units]``, in metres
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass(frozen=True)
class Tolerances:
    """Numerical tolerances (all relative unless the name says otherwise).

    Attributes
    ----------
    volume : float
        Relative fine-volume error accepted as converged, ``|V - V0| / V0``.
    direction : float
        Estimated distance of the cage positions from the fixed point of the
        constrained solve (the a posteriori bound ``rho / (1 - rho) * step``
        of a linearly converging iteration), relative to the size of the
        volume correction, below which the solve counts as stationary.
    mvc_on_vertex : float
        Distance to a cage vertex, relative to the cage's bounding-box
        diagonal, below which a point is treated as lying on that vertex.
    mvc_on_face : float
        Angular tolerance (radians) for a point lying on a cage face.
    mvc_in_plane : float
        Sine of the angle below which a point counts as lying in the plane of
        a cage face (outside the face), whose contribution is then dropped. Its
        true size is proportional to that sine, while the closed formula's
        rounding error grows as its inverse; on the VHF meshes the rest mesh is
        reproduced to at most 3.2e-11 of its size with 1e-7, against 1.4e-10
        (semitendinosus) with 1e-10 and 4.7e-10 with 1e-6
        (``python benchmarks/accuracy/bench_accuracy.py``).
    merge_vertices : float
        Distance, relative to the bounding-box diagonal, under which two mesh
        vertices are merged on load.
    degenerate_area : float
        Triangle area, relative to the squared bounding-box diagonal, under
        which a face counts as degenerate.
    winding_inside : float
        Generalized winding number above which a point counts as enclosed.
    contact : float
        Slack of the contact finish, in mean edge lengths of the muscle: a vertex
        is pushed to the margin plus this much, and counts as violating the
        margin only when it is closer than the margin less this much.
    """

    volume: float = 1e-9
    direction: float = 1e-4
    mvc_on_vertex: float = 1e-12
    mvc_on_face: float = 1e-10
    mvc_in_plane: float = 1e-7
    merge_vertices: float = 1e-10
    degenerate_area: float = 1e-14
    winding_inside: float = 0.5
    contact: float = 0.01


@dataclass(frozen=True)
class Defaults:
    """Default settings of the pipeline.

    Attributes
    ----------
    cage_size : int
        Target number of cage vertices.
    cage_offset : float
        Offset of the cage from the muscle surface, as a fraction of the
        muscle's mean thickness (``4 * volume / area``), clamped by
        ``cage_offset_max``.
    cage_offset_max : float
        Upper bound of the offset as a fraction of the bounding-box diagonal.
    cage_margin : float
        Minimum distance from any fine vertex to the cage, as a fraction of
        the offset, that the cage check demands.
    proxy_size : int
        Number of faces of the intermediate proxy mesh used for the volume
        gradient direction.
    skeleton_weight : float
        Weight of the skeleton condition relative to the Laplacian condition.
    anchor_weight : float
        Weight of the anchors (fine vertices held at their rest positions, where
        a muscle starts on a bone of its own body) relative to the Laplacian,
        scaled as the skeleton's by ``sqrt(m / k)`` for ``k`` anchors. Swept on the
        LHDL hip sweeps (``benchmarks/tuning/bench_anchor_weight.py``, BENCHMARKS.md): the
        iliacus's largest shape change in flexion is 0.49 / 0.48 / 0.48 / 0.51 /
        0.52 mean edges at 0.5 / 0.6 / 0.7 / 0.8 / 1, every other muscle and sweep
        <= 0.42 at all of them; 0.6 is the middle of the range that keeps 0.5.
    anchor_feather : int
        The anchors' weight grows from the rim of their patch inward, to its full
        value this many rings (of the fine mesh) in (0: every anchor at full
        weight).
    anchor_reach : float
        A muscle vertex within this many mean edge lengths of the margin of a bone
        of its own body at the rest pose is an anchor (scenes with contact).
    anchor_end_reach : float
        Of those, only a patch (connected on the mesh) whose nearest vertex lies
        within this fraction of a path's length of that path's first or last
        point is kept: an attachment, where the muscle starts on the bone, not a
        bone the muscle merely lies on at rest and slides over (the psoas on the
        pelvic brim).
    kept_overlap_rings : int
        A rest overlap kept (``rest_overlap = "keep"``): each vertex may go as deep into
        the bone as the deepest of its neighbours within this many rings did at rest
        (0: as deep as itself), for the muscle slides a little along the bone through a
        motion. Rajagopal 2016's generic pelvis and sacrum under the VHF gluteus maximus
        (kept 9.1 and 5.7 mm deep), the walk every 10th frame, the muscle alone with its
        bones and no side from inside a bone (`SideReference.inside`): shape change over
        0.5 on 5 of 22 frames (up to 1.86) with 0, none with 2 (<= 0.46) or 4 (<= 0.46;
        BENCHMARKS.md, a scratch script).
    side_inside_spacings : float
        A vertex that lay inside a bone at its waypoint (or at rest) deeper than this
        many of the bone's grid spacings has no side of it it came from
        (`musclewrap.contact.SideReference.inside`): a kept rest overlap, not a vertex
        that came through. Shallower, it keeps its side (a contact at the margin lies a
        hair inside by its interpolated distance). Rajagopal 2016's 18-muscle scene, the
        walk every 10th frame stepped together (BENCHMARKS.md, thresholds): 0.25 and 1
        keep every shape change <= 0.5 (0.37, 0.40), 4 and no rule (inf) do not (the
        gluteus maximus 0.90 and 0.60, each on one frame); in another muscle 0.13, 0.09,
        0.19 and 0.13 mm. The LHDL walk is the same bytes at 0.25, 1 and 4.
    attached_weight : float
        Weight of the fibres' attachment areas held to their paths' first and last
        points (``[fibres] attached``, the default), relative to the Laplacian and
        scaled as the skeleton's by ``sqrt(m / k)`` for ``k`` such vertices. On the
        LHDL hip sweeps (BENCHMARKS.md, "Attachment areas held to their paths' ends")
        the mean cover of the published fibre moment-arm ranges is 61.7 / 68.5 / 70.5 %
        at 0.6 / 1.8 / 3.6 (53.5 % free), every interior frame within 2.67 / 2.78 /
        2.85 mm of its neighbours' median; past 1.8 the psoas's rotation range grows
        wider than the published one.
    fibre_area_reach : float
        The fibres' attachment areas from the anatomy
        (`musclewrap.fibres.areas_on_bones`): a muscle vertex within this many of
        its mean edge lengths of the margin of a bone of the body its lines start
        (end) in, at rest, lies on its origin's (insertion's) bone.
    fibre_area_end_part : float
        Of those, only vertices in this fraction of the muscle's extent along its
        lines on that end's side. On the LHDL sweeps 0.5 (its half) took the
        gluteus maximus's contact with the greater trochanter (0.56-0.71 of its
        extent) for its insertion: 39 % of its published flexion range covered, 47
        fibre-frames off; 0.3: 60 % and 31 (BENCHMARKS.md, "Attachment areas").
    fibre_area_end_reach : float
        Of those, only patches (connected on the mesh) that come within this
        fraction of a path's length of that path's first (last) point: where the
        muscle attaches, not a bone it lies on or passes over.
    fibre_area_least : int
        A side with fewer such vertices takes its end cap instead.
    samples_per_line : int
        Minimum number of arc-length samples per action line.
    line_window : float
        The default of `Muscle.bind`'s ``line_window`` (a scene's ``line_window``):
        each sample of a current action line is the line's mean over a window this
        many sample spacings (half the cage's mean edge) either side of it, along the
        rest line, narrowed to the line's ends (`musclewrap.conditions.window_mean`),
        so a point of the path sliding past a sample does not kink the sample's way
        through the poses, which steps the fibres' moment arms (the psoas's "stairs",
        issue 48). 0: each sample is the line's point at its arc length. Measured
        (BENCHMARKS.md, "The psoas's stairs"): at 0 the psoas's fibres step by 2.0 mm
        and the iliacus's by 3.9 mm between poses 0.1 deg of hip flexion apart; at 0.5
        and 1 by none over 0.5 mm. 1 creases the LHDL deep squat's gluteus maximus
        (0.74 of shape change every 4th frame), where a window cuts the corner its path
        turns at a via point; 0.5 keeps it at 0.375 (0: 0.360), every 120-deg and random
        motion of `bench_motions.py` at or under 0.44, and the hip sweeps' fibres smooth
        but for their end frames, their cover of the published ranges 63.4 % (0: 64.8).
    line_reach : float
        A line's samples before the first or after the last that lies within this
        many of the muscle's mean thicknesses (``4 * volume / area``) outside the
        muscle are not bound to it: a model's path runs on through the tendons that
        a segmented mesh leaves out (gait2392's semitendinosus path runs 175 mm
        past the VHF mesh, to the tibia), and there the samples' mean value
        coordinates extrapolate the cage. Measured on either side
        (``benchmarks/tuning/bench_thresholds.py --only reach``, BENCHMARKS.md): that
        semitendinosus's fibre moment arms are smooth from 0.5 to 4 (none off by
        3 mm) and up to 1,208 mm off with every sample bound; below 1 the lines that
        run beside their muscle lose much of their length (adductor longus 56 % at
        0.5). The LHDL model's paths end within 0.5 of their muscles (none cut at 0.5).
    max_iterations : int
        Iteration limit of the default solver (most poses converge in 3-6
        plain iterations).
    plain_iterations : int
        Most plain fixed-point iterations of the default solver before it
        turns to a damped Newton method (for poses where the fixed point
        converges slowly or oscillates).
    newton_rate : float
        Observed rate of the plain fixed point (step over previous step)
        above which the default solver turns to Newton's method at once.
    paper_max_iterations : int
        Iteration limit of ``method="paper"`` (the paper used 100 to 200).
    memory_per_face : float
        Peak memory, in bytes per face of the fine mesh, of checking,
        preparing and deforming a muscle, as measured by
        ``benchmarks/speed/bench_large.py --scene`` (1.25M and 3.1M faces: 3.5 and
        8.3 GiB, a slope of 2.6 KiB per face, with margin). A muscle that
        needs more than the memory available is refused before preparation.
    contact_rounds : int
        Most push-out rounds of the contact finish per pose.
    contact_spread : float
        Radius over which a vertex's push out of an obstacle is spread to its
        neighbours, in multiples of the push (plus one ring), at most 12 rings.
    contact_relax : int
        Relaxation sweeps of the pushes with their neighbours' in the first
        rounds (each sweep halves the difference from the 1-ring mean), so that
        neighbours pushed in different directions do not cross.
    contact_relax_rounds : int
        The first rounds, which relax; the later ones project the vertices
        still too near exactly.
    contact_relax_depth : float
        After its first round, a pose's round relaxes only where its deepest
        push is longer than this, in mean edge lengths: a relaxed push lands
        short of its target and takes another round (the LHDL walk's finish
        pushed a median of 9 vertices by 0.05 edges, in 2-4 rounds of which
        three relaxed; now mostly two). Shallow pushes not relaxed at all
        creased the gluteus maximus on a random hip motion (shape change 0.517
        against the 0.5 asked). The rest pose's push-out relaxes every round it
        would have.
    path_step : float
        Spacing of the waypoints between the rest pose and each frame along a
        rotational coordinate, in degrees (`musclewrap.scene.Waypoints`): contact
        takes its sides from the waypoint before a frame.
    path_step_translation : float
        The same along a translational coordinate, in millimetres.
    contact_cage_steps : int
        Most linearised contact steps of the cage (before the fine finish),
        taken while a vertex is more than a mean fine edge too near a bone.
    contact_cage_depth : float
        The cage's contact steps stop once no vertex is more than this many
        mean edge lengths too near an obstacle (the fine finish takes the rest).
    contact_cage_bone_passes : int
        How many times the cage's steps look for the obstacles' vertices standing
        in the muscle (once its vertices are out) and take them out as conditions on
        its triangles (0: only the fine finish does).
    fold_shape : float
        After the bones' cage steps, a vertex whose shape change (mean edge
        lengths) the steps raised to more than this is a fold
        (`musclewrap.contact.unfold` irons it out): the steps' fine vertices near the
        cage's surface fold along its edges. 0.3: the LHDL walk's largest shape
        change is 0.19, so its outputs are those without unfolding.
    fold_rise : float
        ... and by more than this many mean edge lengths (the LHDL scene's 120-deg
        motions, 128 muscle-frames checked: 6 over 0.5 with 0.1, 4 with 0.02, 11
        without unfolding; BENCHMARKS.md).
    fold_held : float
        Vertices within this many mean edge lengths of a bone's margin stay where
        the steps put them (not unfolded), but for the folds themselves. At 2 (the
        contact band) three of the four traced 120-deg frames kept their folds,
        which lie within a band's reach. Holding the folds among them too kept one
        120-deg frame of the gluteus maximus at 0.63 (0.49 since).
    fold_rings : int
        The unfolded region: the folds and this many rings of the mesh round them.
    contact_bone_depth : float
        An obstacle vertex inside the muscle deeper than the margin plus this
        many mean edge lengths pushes the muscle's nearest triangle past it;
        shallower ones are left (chords of the muscle's triangles over a curved
        bone).
    contact_bone_stretch : float
        `musclewrap.contact.bone_vertices_inside`: round a muscle vertex whose
        triangles' smallest enclosing circles exceed in area this many times the
        ones its convexity rule assumes (1.5 mean edges across), the bone vertices
        near it are held to those triangles' own sag. The gait2392 scene through a
        random motion past anatomy (the sartorius at hip extension -85 deg): at
        3 the run finds the acetabulum 1.34 mm inside it, as libigl does; at 4,
        0.77. On the LHDL walk it costs 0.5-0.7 ms a muscle-frame at 3, 0.9 at 1.5,
        0.3 at 4, and changes no mesh (BENCHMARKS.md, the thresholds' table).
    contact_band : float
        Vertices within this many mean fine edge lengths of an obstacle's
        margin enter the cage's contact step as inequality conditions.
    contact_cage_reach : float
        Longest displacement of a fine vertex near the contact by one cage
        contact step, in multiples of the deepest vertex's need (the step is
        scaled down to it).
    contact_softness : float
        Regularisation of the cage's contact conditions, relative to the mean
        of their own diagonal (0: hard conditions). Softer conditions spread a
        deep push over more of the cage: at deep hip flexion the surface creases
        less (BENCHMARKS.md, "Thresholds, either side").
    contact_stiff_from : int
        From this step of a call of the cage's contact steps after the solve (0: the
        first), each condition is softened by ``contact_softness`` times its own
        diagonal, not the mean of all (`musclewrap.solver._step.cage_push` ``own``).
        The mean left a vertex the cage moves only at a high energy (the 19-muscle
        leg's vastus medialis 13 mm in the model's femur at the running trial's knee
        flexion) meeting less each step (13.0, 7.9, 5.6, 4.9, 4.5, 4.1 mm after the
        six), and the fine finish creased it (0.55). From the first step the LHDL
        squat's gluteus medius creased instead (0.68); from the fourth both stay
        under 0.5 (BENCHMARKS.md, the thresholds' table).
    contact_points_per_cage_vertex : int
        Conditions on points of the surface (another muscle's vertices, or a bone's,
        standing in the muscle) kept per cage vertex in a cage contact step: the
        deepest of those whose coordinate rows that cage vertex leads (all of them
        make dense systems of thousands).
    muscle_rounds : int
        Most rounds per frame in which muscles in contact take each other's
        vertices out (`musclewrap.contact.overlaps`): each takes half the depth.
        Most frames take 1-3; one whose lines drive a muscle 25 mm through another
        (the VHF sartorius and adductor longus, running trial frame 320) 20-30
        (12: 1.4 mm left there, 30: 0.29 mm).
    muscle_share : float
        The share of its depth a vertex inside another muscle is taken out by in
        a round (the other muscle's vertices inside it take theirs).
    muscle_joint : bool
        Muscles that overlap each other in a round take one step of their cages
        together (`musclewrap.solver._group.joint_round`: each overlap one condition on
        both, by its whole depth), not a step each with its share: the default of a
        scene's ``[collisions] together`` and of `musclewrap.solver.deform_together`'s
        ``together``. Off: on the 19-muscle leg every 20th frame of the walk it lowers
        ``skeleton_fit_free`` from 1.55 to 0.39 mm at 1.12x the time, but three
        capsules stacked on a rod end up to 0.44 mean edges inside each other (a step
        each: 0.03; ``tests/test_muscle_contact.py``), and a pose 5e-11 deg away gave
        surfaces 0.19 mm apart (the live view's pose against the run of it written to
        ten decimals: BENCHMARKS.md, "A joint step's conditions pooled").
    muscle_joint_points : int
        In a joint step, the conditions on points of another muscle's surface are
        pooled as a step each pools its own vertices': the deepest this many per
        cage vertex that leads the point (while the group's conditions are at most
        ``muscle_joint_conditions``; one past them).
    muscle_joint_conditions : int
        The conditions of a joint step past which they are pooled one a cage vertex:
        its dual system is dense, its solve cubic in them, and the first round of a
        large group held 8,264 (19 muscles: 8.8 s for that solve). The leg's walk
        every 20th frame took 1.58x a step each with no such bound, 1.12x with 2,000
        and 1.16x with every group pooled one a cage vertex, the same shape change
        and misfit; at the squat's bottom the rounds a frame (median) were 6, 9 and
        12 (BENCHMARKS.md, "A joint step's conditions pooled").
    muscle_overlap_depth : float
        The rounds stop once no vertex is deeper than this many of its muscle's
        mean edge lengths inside another muscle (or after ``muscle_rounds``); a
        muscle whose vertices are all out to that depth takes no step in a round.
    muscle_finish_retry : float
        Where the bones' fine finish, after the muscles' rounds, leaves a vertex deeper
        than this many of its mean edges inside another muscle it is kept apart from (it
        pushes each muscle out of its bones alone), the rounds go on from there (within
        ``muscle_rounds``) and, where they take a step, the finish is taken again, at
        most ``muscle_finish_passes`` times in all. Three
        capsules stacked against a rod and pressed from outside
        (`tests/test_muscle_contact.py`): without it the rounds ended apart after 17
        and the finish pushed the first 7.1 mm (3.6 edges) into the second. On the real
        scenes the finish leaves at most 0.05 mean edges (LHDL walk every 4th frame, the
        LHDL squat's bottom, the 18 muscles every 50th) and 0.114 (the 19-muscle leg every
        20th): no second pass, the same bytes. At 0.05 the leg would take one on 6 of
        its 11 frames; at 2 a stack pressed 1.7 edges into another would stay (BENCHMARKS.md,
        "Rounds again after the bones' finish"); at 0.5, with ``contact_stiff_from``, the
        second press of that test stayed 0.43 edges deep (0.25 and 0.3: 0.027).
    muscle_finish_passes : int
        See ``muscle_finish_retry``.
    muscle_fine_depth : float
        A muscle no deeper than this many of its mean edge lengths inside another
        (nor the other in it) takes its round on its fine vertices by `nudge`
        (`musclewrap.contact.nudge`), not by a step of its cage; deeper, to
        ``muscle_plate_depth``, by `press`'s plate with ``muscle_fine_plate``. Past a
        quarter edge `nudge`'s harmonic spread creases (fine steps to 2 edges by
        `nudge`: frame 716 of the leg at the OpenCap squat's bottom to a shape change
        of 1.85, BENCHMARKS.md, "The squat's bottom, round by round").
    muscle_fine_plate : bool
        A round's fine step deeper than ``muscle_fine_depth`` and no deeper than
        ``muscle_plate_depth`` moves the vertices as a thin plate that meets one-sided
        pushes (`musclewrap.contact.press`: the least change of the uniform Laplacian,
        what the shape change measures); off, such a muscle takes a step of its cage, as
        until 2026-12-04 (the rest state's rounds, `apart_at_rest`, keep `nudge` either
        way). On since 2026-12-04 (BENCHMARKS.md, "The plate past a quarter edge,
        switched on"; one sitting, against it off): the stacked leg at the OpenCap
        squat's bottom (15 frames, 690-760) leaves three frames over 0.5 mm in another
        muscle (0.578 at most; off, six, up to 2.17) and four at the rounds' cap (off,
        six), but two change shape past 0.5 (0.505 and 0.804, the bones' finish after
        the rounds; off, 0.433 at most); the 18 muscles' walk every 10th frame 37.1 s
        against 41.4 s (rounds a frame: a median of 2 against 6); the LHDL walk 16.2
        against 15.8 s.
    muscle_plate_depth : float
        With ``muscle_fine_plate``, the deepest a muscle may be (mean edges, in another
        or another in it) for its round to be a plate; deeper, a step of its cage.
        Either side of ``muscle_fine_depth`` (BENCHMARKS.md, as above): the plate on
        every fine step (``muscle_fine_depth = 0``) took the LHDL walk's frame 179 to
        11 rounds (psoas and iliacus 0.1 edges apart, each plate taking them about a
        hundredth of an edge further) and the walk 14 % longer.
    muscle_plate_weight : float
        How strongly `press` holds its pushes against the plate's bending (a penalty
        beside the Laplacian's rows, whose entries are of order 1): at 100 a push is met
        to about a hundredth of its length, which the step's slack of ``tol.contact``
        edges covers.
    muscle_plate_sets : int
        The most Newton steps `press` takes on its plate (each on the pushes left short,
        those the others carry dropped, as far along as the objective falls). Until
        2026-12-03 every step was taken whole, four at most: on the 47 plates of the 18
        muscles' walk frame 50 they cycled, and ended up to 0.7 mean edges from where
        eight would have (BENCHMARKS.md, "The plate's cost and its steps"). Now a median
        of 8, at most 25 there, before ``muscle_plate_still``.
    muscle_plate_iterations : int
        Conjugate-gradient iterations of a Newton step of `press` (Jacobi-preconditioned,
        from the last step's plate). 15: the 47 plates above in 1.4 s, pushes left short
        by at most 0.023 mean edges (under the step's slack); 30: 2.6 s, 0.012; 60: 4.2 s,
        0.010. A sparse factorisation a step (SuperLU) took 21 s for four steps each.
    muscle_plate_still : float
        `press` stops where a step moves no vertex by more than this many mean edges.
    muscle_plate_rise : float
        `press` gives its step up (the cage takes the round) where it would lengthen
        any vertex's Laplacian vector by more than this many mean edges in one step:
        pushes that disagree (a thin wall pressed from both sides, frame 716's adductor
        magnus: 1.7 edges in one step) bend the plate.
    muscle_plate_shape : float
        `press` gives its step up where it would raise a vertex's shape change
        (`PreparedMuscle.shape_change`) past this many mean edges (0.45: under the 0.5
        the contact tables hold). Without it frame 716 above ends 0.29 mm in another
        muscle with a shape change of 0.62 (the adductor brevis), with it 1.13 mm, 0.44.
    muscle_plate_spread : float
        `press`'s plate spans this many mean edges per edge pushed round the pushes
        (plus one ring, at most 12). At 1, 2 and 3 on frames 716 / 724 above: 1.13 /
        1.77, 0.57 / 1.80 and 0.32 / 2.07 mm in another muscle; shape change 0.44 /
        0.49, 0.45 / 0.58 and 0.42 / 0.79 (wider: the frame it helps it helps more,
        the other it harms more).
    muscle_plate_drop : bool
        `press` leaves out the pushes that disagree (a vertex whose pushes cancel by
        more than half, or neighbours pushed opposite ways) instead of refusing the
        step at its rise bound; the cage takes them. Off.
    contact_round_held : int
        A round's cage step (`Deformer.contact_round`, `joint_round`) is tried, and the
        vertices it put into a bone (more than ``contact_cage_depth`` mean edges, and
        deeper than before by as much) are held by conditions of their own beside the
        deepest of each cage vertex, in the step taken again (`Deformer._stepped_in`),
        at most this many times (0: the step as first tried, as until 2026-12-04). The
        19-muscle leg at the OpenCap squat's bottom (15 frames, one sitting; BENCHMARKS.md,
        "A round's step held off the bones"), frames within every bound / past 0.5 of
        shape change / seconds: 0 tries 10 / 2 / 102, 1 try 14 / 1 / 129, 2 tries 14 / 0
        / 156, 3 tries 14 / 0 / 198.
    muscle_step_reach : float
        A round's cage step moves no fine vertex of its muscle further than this many
        times its deepest need (the step scaled down to it; ``contact_cage_reach`` holds
        only those near the contact). Where the conditions conflict (muscles stacked
        between bones) a step held only there can swing a part of the muscle far from
        every contact into a muscle it had no condition on. The 19-muscle leg at the deep
        squat's bottom, 15 frames (BENCHMARKS.md, "The squat's bottom, round by round"):
        frames deeper than 0.5 mm in another muscle 7 without, 5 at 1, 4 at 0.75, the
        deepest 2.15, 1.24 and 1.99 mm, the largest shape change 0.85, 0.54 and 0.57; at
        2 no step of those frames is held. It costs rounds where they converge anyway
        (the LHDL walk every 4th frame a round more on 40 of 212 muscle-frames).
    muscle_facing_reach : float
        A muscle's faces within this distance (mesh units) of another muscle at
        rest, with the other in front of them, or inside it, are where the other's
        vertices leave it (`musclewrap.contact.facing_faces`). 10 to 1,000 mm leave the
        gait2392 walk's worst frames the same (no vertex over 0.03 mm inside another),
        5 mm 0.75 mm (BENCHMARKS.md, "Thresholds, either side").
    muscle_rest_rounds : int
        Most rounds in which segmented muscles that overlap at rest are taken apart,
        once per run (`musclewrap.contact.apart_at_rest`).
    closest_grid_points : int
        Up to this many points, the closest points on another muscle come from a grid of
        its triangles' centroids; beyond it, libigl's tree (both exact; the last bits of a
        distance and the row taken on a tie may differ). The calls a run makes, each timed
        both ways (`python benchmarks/speed/bench_closest.py --scene SCENE --bins 200 500
        1000 2000 3000`, one process, 2026-11-27): the 18 hip and thigh muscles every 50th
        frame, 201-2,000 points 1.26 s against the tree's 2.89 s, 2,001-3,000 0.17 against
        0.18 s; the gait2392 walk every 10th 0.24 against 0.52 s. The grid's cost grows
        with the points far from the surface (an earlier run's calls of over 5,000 points:
        2.2 against 0.48 s). 200 before.
    fibre_inside_depth : float
        How far inside the surface a fibre point found outside it is put, in grid cells
        of the fibres' field.
    check_far_thicknesses : float
        `musclewrap.run.check_scene`: a muscle's rest lines whose nearest quarter lies
        farther than this many mean thicknesses (4 V / A) outside it are not its lines
        (BENCHMARKS.md, "A user's own subject").
    check_attached_m : float
        `musclewrap.run.check_scene`: a bone's attachments are the path points within
        this distance of it (m, model units).
    view_contact_reach : float
        The viewer's contact colours: vertices within this distance (mesh units) of a
        bone, or of a muscle kept apart from theirs, are coloured as in contact.
    line_conflict_mm : float
        A run's notes name a muscle whose action lines run deeper than this (mm) inside
        a bone (``line_inside_depth_max``): where contact makes the surface leave them
        (``lines_conflict_max``); shallower ones are in report.csv only.
    overlap_note_mm : float
        A run's notes name a muscle with a vertex deeper than this (mm) inside another
        muscle on some frame (``muscle_overlap_max``; the issues' bound, 0.5 mm): where
        the rounds could not take them apart. Shallower ones are in report.csv only.
    bone_note_mm : float
        A run's notes name a muscle with a vertex deeper than this (mm) inside a bone
        on some frame (``penetration_depth_max``; the issues' bound, 0.5 mm).
    bone_inside_note_mm : float
        A run's notes name a muscle with a bone's vertex deeper than this (mm) inside
        it on some frame (``bone_inside_depth_max``; the issues' bound, 1 mm).
    view_moving_triangles : int
        The viewer draws about this many triangles in all (muscles and bones, each
        decimated in proportion, never below a tenth of its own) while a slider moves,
        and every triangle when it stops: a software-drawing browser's redraw grows with
        the triangles (BENCHMARKS.md, "The viewer").
    init_alike_deg : float
        `musclewrap.subject.init_scene`: two registrations whose rotations differ by less
        than this (degrees) are the same placement.
    init_far : float
        `musclewrap.subject.init_scene` writes no scene where the best placement leaves
        the median muscle's paths further than this many of its extents from it (the
        distance a quarter of their length is within): the meshes are not where the
        model's paths run, and a scene would place them there. The VHF folder on
        gait2392 (registered) and on Rajagopal 2016, and the LHDL meshes on their model,
        give at most 0.0006; the VHF folder whose hip cartilages' names say nothing and
        without the knee's, 3.4
        (``python benchmarks/tuning/bench_shapes.py --placements``).
    init_cap_rms : float
        `musclewrap.subject.init_scene`: a mesh no name places is the hip's cartilage
        when the rms distance from its fitted sphere is under this fraction of the
        radius (and it is a cap, not a band: `musclewrap.model.cap_spread` >= 0.15). The
        VHF femoral head's and acetabulum's cartilages fit to 0.052 and 0.030 (spread
        0.27, 0.19); rounder or as round VHF muscles are bands (the sartorius 0.012,
        the iliacus 0.099, the gracilis 0.104: spread <= 0.04); of the meshes spread
        0.15 or more the nearest fits to 0.144 (the distal femur's cartilage)
        (``python benchmarks/tuning/bench_shapes.py``).
    init_shell : float
        `musclewrap.subject.init_scene`: a closed mesh whose mean thickness (4 V / A) is
        under this fraction of its width (its second principal extent), and under half
        the median mean thickness of the folder's meshes named as muscles (where it names
        any: a flat muscle as thick as the others stays a muscle), is a thin shell, never
        a muscle, whatever its name says. The VHF cartilages measure 0.053-0.085 of
        their width and 0.11-0.18 of the median muscle; the thinnest other shared meshes
        are the LHDL iliac bone (0.139) and sacrum (0.156), the thinnest muscle the LHDL
        iliacus (0.168); the thinnest VHF muscle, the sartorius, is 0.66 of the median
        (``python benchmarks/tuning/bench_shapes.py``). A flat muscle such as an abdominal
        oblique would measure about 0.11 (an estimate from its published size: no shared
        folder holds one), hence the second test.
    init_bone_place : float
        `musclewrap.subject.init_scene` takes a closed solid no name places for the
        model's bone of a body when the mean distance between the two (each's vertices
        to the other's, the larger) is under this fraction of its diagonal. The VHF
        tibia on gait2392's and Rajagopal 2016's tibia (registered): 0.031 and 0.044; the
        nearest muscle to a model bone, the sartorius on the femur: 0.108-0.110; the VHF
        patella on Rajagopal's, 0.141, is not taken
        (``python benchmarks/tuning/bench_shapes.py --places``).
    init_place_tie : float
        `musclewrap.subject.init_scene` takes a mesh no name places for the muscle whose
        paths run along it (the one-to-one assignment of such meshes to the paths no
        named mesh took), unless the best assignment that gives it another muscle (or
        none) costs less than this many of its mean thicknesses more: then it fits two
        alike and is placed nowhere, said. The VHF folder with all but three muscles
        named Segment_N.stl: on gait2392 each of 16 is taken for its own muscle, margins
        0.026-0.94; on Rajagopal 2016 14 of 15, margins 0.010-0.86, and the
        semitendinosus is taken for the biceps femoris long head (margin 0.18): place
        cannot tell apart neighbours whose paths run alike, names can. At 0.05, four of
        the right ones (margins 0.010-0.033) would be left unplaced
        (``python benchmarks/tuning/bench_shapes.py --places``).
    """

    cage_size: int = 300
    cage_offset: float = 0.15
    cage_offset_max: float = 0.015
    cage_margin: float = 0.25
    proxy_size: int = 1000
    skeleton_weight: float = 1.0
    anchor_weight: float = 0.6
    anchor_feather: int = 4
    anchor_reach: float = 0.5
    anchor_end_reach: float = 0.15
    kept_overlap_rings: int = 2
    side_inside_spacings: float = 1.0
    attached_weight: float = 1.8
    fibre_area_reach: float = 1.0
    fibre_area_end_reach: float = 0.15
    fibre_area_end_part: float = 0.3
    fibre_area_least: int = 10
    samples_per_line: int = 33
    line_window: float = 0.5
    line_reach: float = 1.0
    max_iterations: int = 60
    plain_iterations: int = 30
    newton_rate: float = 0.85
    paper_max_iterations: int = 200
    memory_per_face: float = 3000.0
    contact_rounds: int = 12
    contact_spread: float = 1.0
    contact_relax: int = 4
    contact_relax_rounds: int = 3
    contact_relax_depth: float = 0.25
    contact_cage_steps: int = 6
    path_step: float = 10.0
    path_step_translation: float = 20.0
    contact_cage_depth: float = 0.25
    contact_cage_bone_passes: int = 1
    fold_shape: float = 0.3
    fold_held: float = 0.4
    fold_rise: float = 0.02
    fold_rings: int = 2
    contact_bone_depth: float = 0.1
    contact_bone_stretch: float = 3.0
    contact_band: float = 2.0
    contact_softness: float = 0.5
    contact_cage_reach: float = 1.25
    contact_stiff_from: int = 3
    contact_points_per_cage_vertex: int = 3
    muscle_rounds: int = 30
    muscle_share: float = 0.5
    muscle_joint: bool = False
    muscle_joint_points: int = 3
    muscle_joint_conditions: int = 2000
    muscle_overlap_depth: float = 0.05
    muscle_fine_depth: float = 0.25
    muscle_fine_plate: bool = True
    muscle_plate_depth: float = 2.0
    muscle_plate_weight: float = 100.0
    muscle_plate_sets: int = 30
    muscle_plate_iterations: int = 15
    muscle_plate_still: float = 0.01
    muscle_plate_rise: float = 0.25
    muscle_plate_shape: float = 0.45
    muscle_plate_spread: float = 1.0
    muscle_plate_drop: bool = False
    contact_round_held: int = 2
    muscle_step_reach: float = 1.0
    muscle_finish_retry: float = 0.25
    muscle_finish_passes: int = 3
    muscle_facing_reach: float = 15.0
    muscle_rest_rounds: int = 30
    closest_grid_points: int = 2000
    fibre_inside_depth: float = 0.1
    check_far_thicknesses: float = 1.0
    check_attached_m: float = 0.010
    view_contact_reach: float = 5.0
    view_moving_triangles: int = 15_000
    line_conflict_mm: float = 0.5
    overlap_note_mm: float = 0.5
    bone_note_mm: float = 0.5
    bone_inside_note_mm: float = 1.0
    init_alike_deg: float = 15.0
    init_far: float = 0.25
    init_cap_rms: float = 0.08
    init_shell: float = 0.11
    init_bone_place: float = 0.06
    init_place_tie: float = 0.01


tol = Tolerances()
defaults = Defaults()
