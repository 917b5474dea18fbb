"""A Franka Panda arm in a world's pybullet client, holding a container.

The arm is ``pybullet_data``'s ``franka_panda/panda.urdf`` (the model panda-gym uses),
fixed to the table at its base. It is moved kinematically: every step its seven joints go
to targets within their limits and at most their velocity limits, and the held container
is rigidly attached to the hand (its pose is the hand's pose times the grasp), so the cup
cannot slip however fast the arm moves. Collisions are queries of pybullet's closest
points between the arm, the held container, the other containers and the table, made
after every move.

The grasp (:func:`grasp`) is a plain function of the container's labelled mesh: a cup is
held by its handle (the fingers close across the handle's thin side, the hand approaching
the cup horizontally), a container without a handle is pinched on its rim wall from above,
the fingers closing across the wall, on the side away from its lip. The Panda's fingers
open 80 mm; both grasps need far less.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet_data

from pour_gym.assets import LabelledAsset
from pour_gym.fluid.colliders import quaternion
from pour_gym.parts import Part
from pour_gym.sim.rotations import as_rotvec

URDF = "franka_panda/panda.urdf"
ARM_JOINTS = tuple(range(7))
FINGER_JOINTS = (9, 10)
# The frame between the fingertips (panda_grasptarget, 0.105 m beyond the hand).
GRASP_LINK = 11
# The moving links (pybullet's link j is joint j's child: panda_link1 ... the fingers); the
# base (link -1) stands on the table.
ARM_LINKS = tuple(range(11))
# Where the arm stands: at the table's edge beside Pour-v0's workspace (the source starts
# at the origin and pours towards +x), reaching along +y.
BASE_POSITION = (0.0, -0.6, 0.0)
BASE_YAW = np.pi / 2  # rad
# Rest poses (rad) for inverse kinematics, one per grasp. A rim is pinched from above: the
# hand points down, elbow up. A handle is held with the hand horizontal, and tilting turns
# the wrist: a pose from which pybullet's solver, step by step, follows a tilt from 0 to
# 135 deg with the lip held still (found by a search over 400 random starting poses; from
# the hand-down pose the solver stalls at a joint limit 0.3 m from the goal).
REST_POSES = {
    "rim": (0.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785),
    "handle": (-1.52, 0.69, 1.17, -2.64, 2.74, 2.0, -2.86),
}
# The rest poses for a grasp turned half a turn about the hand's approach
# (:meth:`Grasp.turned`): the last joint half a turn away.
TURNED_REST_POSES = {
    kind: (*pose[:-1], pose[-1] + (np.pi if pose[-1] < 0.0 else -np.pi))
    for kind, pose in REST_POSES.items()
}
# Starting poses for the grasp at reset besides the rest pose: the rest pose with the
# shoulder, forearm and wrist turned (rad), for grasps the rest pose reaches only with a
# joint at its limit.
SEED_OFFSETS = tuple(
    tuple(d if j == k else 0.0 for j in range(7)) for k in (0, 4, 6) for d in (-0.5, 0.5)
)
# Handle vertices this far from the handle's outermost point are the part the fingers hold.
HANDLE_GRIP = 0.012  # m
# A rim is pinched this far below its top (the finger pads are 2 cm long).
RIM_GRIP_DEPTH = 0.012  # m
# Pose errors add metres and radians times this (an angle's arc at a cup's size).
ORIENTATION_SCALE = 0.1  # m/rad
IK_ITERATIONS = 100
IK_RESIDUAL = 1e-5
# Iterations of the local solve in :meth:`Panda.follow` (a step's worth of motion).
LOCAL_ITERATIONS = 10
# Iterations, damping (m) and finite-difference step (rad) of :meth:`Panda.solve_held`.
HELD_ITERATIONS = 30
HELD_DAMPING = 0.02
HELD_DIFFERENCE = 1e-5
# A step whose pose error is below this (m, plus 0.1 m per rad) is taken as it is.
ON_POSE = 1e-4
# How far from the commanded orientation a step of :meth:`Panda.follow` may leave the
# container when it is not already farther (rad).
TURN_SLACK = np.radians(0.5)


@dataclass(frozen=True)
class Grasp:
    """Where the hand holds a container, in the container's frame.

    Attributes:
        position: (3,) the point between the fingertips, m.
        rotation: (3, 3) the grasp frame's axes as columns: x, y (the fingers close along
            it), z (the hand approaches along it).
        width: what the fingers close on, m (the finger opening).
        kind: ``"handle"`` or ``"rim"``.
    """

    position: np.ndarray
    rotation: np.ndarray
    width: float
    kind: str

    def turned(self) -> Grasp:
        """The same grasp with the hand turned half a turn about its approach.

        Two parallel fingers hold a handle or a rim wall alike either way round; the arm's
        last joint then stands half a turn away, which frees a wrist held at its limit.
        """
        return Grasp(self.position, self.rotation @ np.diag([-1.0, -1.0, 1.0]), self.width,
                     self.kind)  # fmt: skip


def grasp(asset: LabelledAsset) -> Grasp:
    """The grasp of a labelled container: its handle if it has one, else its rim wall.

    A handle is held at its outermost part (the vertices within ``HANDLE_GRIP`` of its
    farthest point from the rim's axis), the hand approaching towards the axis, the
    fingers closing across the handle (horizontally, perpendicular to that approach). A
    container without a handle is pinched from above, ``RIM_GRIP_DEPTH`` below the top of
    its rim, across its wall, on its +x side (Pour-v0 holds a source with its lip on the
    -x side of its frame).

    Args:
        asset: the container (its mesh, labels and geometry, upright, in m).
    """
    g = asset.geometry
    v = np.asarray(asset.surface.vertices)
    axis = g.rim_center[:2]
    handle = v[asset.labels == Part.HANDLE]
    if len(handle):
        radial = np.hypot(*(handle[:, :2] - axis).T)
        # Only the part that stands off the body (a labelling may stray onto the body).
        handle = handle[radial > g.rim_radius]
    if len(handle) >= 3:
        radial = np.hypot(*(handle[:, :2] - axis).T)
        held = handle[radial > radial.max() - HANDLE_GRIP]
        point = held.mean(axis=0)
        out = np.append(point[:2] - axis, 0.0)
        out /= np.linalg.norm(out)
        approach = -out  # towards the cup's axis
        across = np.cross([0.0, 0.0, 1.0], out)  # horizontal, across the handle
        width = float(np.ptp(held @ across))
        rot = np.column_stack([np.cross(across, approach), across, approach])
        return Grasp(point, rot, min(width, 0.08), "handle")
    rim = np.asarray(g.rim_vertices)
    k = int(np.argmax(rim[:, 0]))
    top = float(rim[:, 2].max())
    point = np.array([rim[k, 0] - 0.002, rim[k, 1], top - RIM_GRIP_DEPTH])
    across = np.array([1.0, 0.0, 0.0])  # the wall's normal at +x
    approach = np.array([0.0, 0.0, -1.0])
    rot = np.column_stack([np.cross(across, approach), across, approach])
    return Grasp(point, rot, 0.004, "rim")


class Panda:
    """The arm in a pybullet client: joints, inverse kinematics, the hand's pose, contacts.

    Args:
        client: the world's pybullet client.
        base: (3,) where the arm's base stands on the table, m.
    """

    def __init__(self, client, base=BASE_POSITION, yaw: float = BASE_YAW):
        self.client = client
        client.setAdditionalSearchPath(pybullet_data.getDataPath())
        turn = [0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2))]
        self.body = client.loadURDF(URDF, list(base), turn, useFixedBase=True)
        # The base's URDF frame (pybullet reports the base's centre of mass instead).
        self._base_frame = np.eye(4)
        self._base_frame[:3, :3] = np.array(client.getMatrixFromQuaternion(turn)).reshape(3, 3)
        self._base_frame[:3, 3] = base
        # Bound once: a BulletClient wraps the function anew at every attribute lookup.
        self._reset_joints = client.resetJointStatesMultiDof
        info = [client.getJointInfo(self.body, j) for j in ARM_JOINTS]
        self.lower = np.array([i[8] for i in info])
        self.upper = np.array([i[9] for i in info])
        self.max_velocity = np.array([i[11] for i in info])  # rad/s
        self.rest = np.array(REST_POSES["rim"])
        self.set_joints(self.rest)

    @property
    def joints(self) -> np.ndarray:
        """(7,) joint positions, rad."""
        return np.array([s[0] for s in self.client.getJointStates(self.body, ARM_JOINTS)])

    def set_joints(self, q: np.ndarray, fingers: float | None = None) -> None:
        """Put the joints at ``q`` (rad) and, if given, each finger ``fingers`` m open."""
        # One call for the seven (a step sets them 10-20 times: solves, candidate poses).
        self._reset_joints(self.body, ARM_JOINTS, [[float(v)] for v in q])
        if fingers is not None:
            self._reset_joints(self.body, FINGER_JOINTS, [[float(fingers)]] * len(FINGER_JOINTS))

    def visual_meshes(self) -> list[tuple[int, object, np.ndarray]]:
        """The arm's drawn meshes: ``(link, trimesh mesh, (4, 4) frame in the link's)``.

        Link -1 is the base. Read from the URDF's visual shapes (``pybullet_data``'s OBJ
        files), in the order pybullet lists them.
        """
        import trimesh

        shapes = []
        for shape in self.client.getVisualShapeData(self.body):
            link, scale, filename, position, orientation = (
                shape[1], shape[3], shape[4].decode(), shape[5], shape[6]
            )  # fmt: skip
            mesh = trimesh.load(filename, force="mesh", process=False)
            mesh.apply_scale(np.asarray(scale, dtype=np.float64))
            local = np.eye(4)
            local[:3, :3] = np.array(self.client.getMatrixFromQuaternion(orientation)).reshape(3, 3)
            local[:3, 3] = position
            shapes.append((int(link), mesh, local))
        return shapes

    def link_frames(self, links) -> dict[int, np.ndarray]:
        """The links' URDF frames in the world as (4, 4) matrices (link -1: the base)."""
        frames = {}
        for link in links:
            if link < 0:
                frames[link] = self._base_frame
                continue
            state = self.client.getLinkState(self.body, link, computeForwardKinematics=True)
            frame = np.eye(4)
            frame[:3, :3] = np.array(self.client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            frame[:3, 3] = state[4]
            frames[link] = frame
        return frames

    def hand_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The grasp frame's (position (3,), rotation (3, 3)) in the world."""
        state = self.client.getLinkState(self.body, GRASP_LINK, computeForwardKinematics=True)
        rot = np.array(self.client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
        return np.array(state[4]), rot

    def solve(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        passes: int = 2,
        iterations: int = IK_ITERATIONS,
    ) -> np.ndarray:
        """Joint positions (rad, within the limits) that put the grasp frame at a pose.

        Pybullet's damped-least-squares inverse kinematics with the joint limits and the
        rest pose in its null space, from the current joints, ``passes`` times (each from
        the last solution; the first pass alone leaves up to a few mm on large moves). The
        joints are left where they were.

        Args:
            position: (3,) m, world.
            rotation: (3, 3), world.
            passes: solves in a row.
            iterations: the solver's iterations per pass.
        """
        start = self.joints
        w, x, y, z = quaternion(rotation)
        q = start
        for _ in range(passes):
            solution = self.client.calculateInverseKinematics(
                self.body,
                GRASP_LINK,
                np.asarray(position).tolist(),
                [x, y, z, w],
                lowerLimits=self.lower.tolist(),
                upperLimits=self.upper.tolist(),
                jointRanges=(self.upper - self.lower).tolist(),
                restPoses=self.rest.tolist(),
                maxNumIterations=iterations,
                residualThreshold=IK_RESIDUAL,
            )
            q = np.clip(np.array(solution[: len(ARM_JOINTS)]), self.lower, self.upper)
            self.set_joints(q)
        self.set_joints(start)
        return q

    def pose_errors(
        self, q: np.ndarray, position: np.ndarray, rotation: np.ndarray
    ) -> tuple[float, float]:
        """How far the grasp frame at joints ``q`` is from a pose: (metres, radians).

        The joints are left where they were.
        """
        start = self.joints
        self.set_joints(q)
        p, r = self.hand_pose()
        self.set_joints(start)
        cos = np.clip((np.trace(r.T @ rotation) - 1.0) / 2.0, -1.0, 1.0)
        return float(np.linalg.norm(p - position)), float(np.arccos(cos))

    def pose_error(self, q: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> float:
        """:meth:`pose_errors` as one number: metres plus 0.1 m per rad."""
        metres, radians = self.pose_errors(q, position, rotation)
        return metres + ORIENTATION_SCALE * radians

    def reach(self, position: np.ndarray, rotation: np.ndarray, seeds) -> np.ndarray:
        """Joints that put the grasp frame at a pose, the best from several starting poses.

        From each seed, three rounds of :meth:`solve`; the solution nearest the pose wins,
        and of those as near to the millimetre the one with the fewest joints at a limit (a
        joint at its limit cannot follow the motion that comes next). The joints are left
        where they were.

        Args:
            position: (3,) m, world.
            rotation: (3, 3), world.
            seeds: starting joint positions (each (7,), rad).
        """
        start = self.joints
        best, best_key = start, (np.inf, np.inf)
        for seed in seeds:
            self.set_joints(seed)
            for _ in range(3):
                self.set_joints(self.solve(position, rotation))
            q = self.joints
            error = self.pose_error(q, position, rotation)
            key = (round(error, 3), float(np.count_nonzero(self.at_limit(q))) + error)
            if key < best_key:
                best, best_key = q, key
        self.set_joints(start)
        return best

    def follow(
        self, position: np.ndarray, rotation: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The joints of one step of ``dt`` s that bring the grasp frame nearest a pose.

        The step the joints' limits and velocities allow (:meth:`limit`) towards the
        solver's solution (:meth:`solve`) is taken if it lands on the pose (within
        ``ON_POSE``: the usual case). Otherwise three goals: that solution, a local one (a
        few iterations from the current joints, which stays on the arm's current branch of
        solutions when the first lies on another, far in joint space) and, with a joint at
        a limit, one that moves only the others (:meth:`solve_held`); towards each, the
        allowed step and half and a quarter of it; of these the one nearest the pose
        (metres plus 0.1 m per rad) is taken if it is nearer than staying and leaves the
        container no further from the commanded orientation than it is (or than
        ``TURN_SLACK``). So where a joint limit or another branch bends the way, the arm
        stays rather than swing or tip the cup away from the pose it was sent to.

        Returns:
            ``(q, clipped)`` as :meth:`limit`; a joint counts as clipped where the step
            taken is not the whole allowed step to the solver's solution.
        """
        q0 = self.joints
        solution = self.solve(position, rotation)
        q1, clipped = self.limit(solution, dt)
        if self.pose_error(q1, position, rotation) < ON_POSE:
            return q1, clipped
        metres, turned = self.pose_errors(q0, position, rotation)
        best, best_error = q0, metres + ORIENTATION_SCALE * turned
        # No step may turn the container further from the commanded orientation than it
        # is (or than TURN_SLACK): nearing the lip's position by tilting the cup would pour
        # it, a little at every step.
        most_turn = max(turned, TURN_SLACK)
        local = self.solve(position, rotation, passes=1, iterations=LOCAL_ITERATIONS)
        # The held solve is for an orientation the limit keeps the arm from: it may not
        # leave the container any further from the commanded orientation than it is (it
        # would otherwise near an unreachable position by tipping the cup, TURN_SLACK at
        # every step).
        goals = [(solution, most_turn), (local, most_turn)]
        if self.at_limit(q0).any():
            goals.append((self.solve_held(position, rotation), turned))
        for goal, turn in goals:
            step, _ = self.limit(goal, dt)
            for fraction in (1.0, 0.5, 0.25):
                q = q0 + fraction * (step - q0)
                metres, radians = self.pose_errors(q, position, rotation)
                error = metres + ORIENTATION_SCALE * radians
                if radians <= turn and error < best_error - 1e-9:
                    best, best_error = q, error
        return best, clipped | ~np.isclose(best, q1, rtol=0.0, atol=1e-9)

    def solve_held(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """Joints nearer a pose, moving only the joints that are not at a limit.

        Damped least squares on the grasp frame's position and orientation errors, with a
        finite-difference Jacobian of the free joints; a joint that reaches its limit is
        held there too. Pybullet's solver, from joints at a limit, can return solutions
        that the limit clips back to where they were: the pybullet mug's cup, held by its
        handle with the forearm joint at its limit, stopped tilting at 81 deg for good,
        short of the tilt its pour needed, though the other six joints could tilt it
        further. The joints are left where they were.
        """
        start = self.joints
        q = start.copy()
        held = self.at_limit(q)
        for _ in range(HELD_ITERATIONS):
            self.set_joints(q)
            p, r = self.hand_pose()
            error = np.concatenate([position - p, as_rotvec(rotation @ r.T)])
            jacobian = np.zeros((6, len(ARM_JOINTS)))
            for j in np.flatnonzero(~held):
                moved = q.copy()
                moved[j] += HELD_DIFFERENCE
                self.set_joints(moved)
                pj, rj = self.hand_pose()
                jacobian[:3, j] = (pj - p) / HELD_DIFFERENCE
                jacobian[3:, j] = as_rotvec(rj @ r.T) / HELD_DIFFERENCE
            normal = jacobian @ jacobian.T + HELD_DAMPING**2 * np.eye(6)
            q = np.clip(q + jacobian.T @ np.linalg.solve(normal, error), self.lower, self.upper)
            held |= (q <= self.lower) | (q >= self.upper)
        self.set_joints(start)
        return q

    def limit(self, goal: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The joints a step of ``dt`` s reaches towards ``goal``, and which joints clipped.

        Within the joint limits and moving each joint at most its velocity limit.

        Returns:
            ``(q, clipped)``: (7,) rad; (7,) bool, true where a limit held the joint back.
        """
        q = self.joints
        most = self.max_velocity * dt
        step = np.clip(goal - q, -most, most)
        target = np.clip(q + step, self.lower, self.upper)
        clipped = ~np.isclose(target, goal, rtol=0.0, atol=1e-6)
        return target, clipped

    def at_limit(self, q: np.ndarray, margin: float = 0.02) -> np.ndarray:
        """(7,) bool: joints within ``margin`` rad of a limit."""
        return (q < self.lower + margin) | (q > self.upper - margin)

    def normalised(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """(14,) joint positions over their range (-1 to 1) and velocities over their limits."""
        mid, half = 0.5 * (self.upper + self.lower), 0.5 * (self.upper - self.lower)
        return np.concatenate([(q - mid) / half, qd / self.max_velocity])

    def touching(self, other: int, links=ARM_LINKS, margin: float = 0.0) -> bool:
        """Whether any of the arm's ``links`` is within ``margin`` m of body ``other``."""
        # One query for the whole arm (a point's fourth field is the arm's link), not one
        # per link: this runs twice every step.
        points = self.client.getClosestPoints(self.body, other, margin)
        return any(point[3] in links for point in points)
