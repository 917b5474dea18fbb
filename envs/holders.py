"""What holds the source container in a pouring env: nothing (it floats), or a robot arm.

The pouring task (:class:`~pour_gym.envs.pour.PourEnv`) composes a holder, as panda-gym
composes a robot with a task: the task owns the containers, the fluid, the observation,
the reward and the endings; the holder owns how a command moves the source, what extra
inputs, costs and failures the holding body brings, and its part of ``info``.
``PourGym/Pour-v0`` is the task with :class:`FreeHolder`, ``PourGym/PandaPour-v0`` with
:class:`PandaHolder`; a second arm is a new holder in :data:`HOLDERS`, not a new env.

A holder is a part: it never sees the env. At reset it is given the episode's
:class:`HeldScene` (the world, the two containers, the source's :class:`SourceFrame`) and
where the lip and the tilt start; each step it takes a command (the lip and the tilt the
task commands, and the raw action for holders that read joints from it) and returns the
pose it reached (:class:`Reached`); its failure, observation, info and reward terms are
read from it afterwards.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from gymnasium import spaces

from pour_gym.errors import InputError
from pour_gym.sim import Camera
from pour_gym.sim.panda import (
    ARM_JOINTS,
    REST_POSES,
    SEED_OFFSETS,
    TURNED_REST_POSES,
    Grasp,
    Panda,
    grasp,
)
from pour_gym.sim.rotations import about_z
from pour_gym.sim.sensors import SEGMENTS, Body, Sensor

if TYPE_CHECKING:
    from pour_gym.features import ContainerGeometry
    from pour_gym.sim import Container, World

PANDA_CONTROLS = ("ee", "joints")
# The arm's colour in the sensors' rgb pictures (pybullet draws it white and grey).
ARM_COLOR = (0.80, 0.80, 0.82)
# The arm takes a grasp at reset when its pose error is below this (m, plus 0.1 m per rad).
REACHED = 2e-3
JOINT_NAMES = tuple(f"joint{j + 1}_position" for j in ARM_JOINTS) + tuple(
    f"joint{j + 1}_velocity" for j in ARM_JOINTS
)


@dataclass(frozen=True)
class SourceFrame:
    """How the source is carried: its upright rotation and its lip in its own frame.

    Attributes:
        base_rotation: (3, 3) the source's rotation when upright.
        lip_local: (3,) the lip in the source's frame, m.
    """

    base_rotation: np.ndarray
    lip_local: np.ndarray

    def rotation(self, tilt_deg: float) -> np.ndarray:
        """The source's rotation at a tilt (deg) towards +x, its lip facing the target."""
        # About y by hand: SciPy's Rotation objects cost more than the rest of a step's
        # bookkeeping together.
        c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ self.base_rotation

    def pose(self, lip: np.ndarray, tilt_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """The source's (position, rotation) with its lip at ``lip`` (m), tilted (deg)."""
        rot = self.rotation(tilt_deg)
        return lip - rot @ self.lip_local, rot

    def lip_tilt(self, position: np.ndarray, rotation: np.ndarray) -> Reached:
        """The lip (m) and the tilt (deg) of the source at a pose."""
        # The task tilts about y: the container's axis is (sin tilt, 0, cos tilt).
        tilt = float(np.degrees(np.arctan2(rotation[0, 2], rotation[2, 2])))
        return Reached(rotation @ self.lip_local + position, tilt)


@dataclass(frozen=True)
class Reached:
    """Where the holder put the source: its lip (m, world) and its tilt (deg)."""

    lip: np.ndarray
    tilt: float


@dataclass(frozen=True)
class HeldScene:
    """What a holder works on in an episode: no env, only its parts.

    Attributes:
        world: the episode's world (its pybullet client, its containers' poses).
        source: the held container.
        target: the container poured into (a body not to touch).
        frame: how the source is carried.
        source_name: the source's container name (a grasp is kept per name).
    """

    world: World
    source: Container
    target: Container
    frame: SourceFrame
    source_name: str


class Holder:
    """The source's holder: the part :class:`~pour_gym.envs.pour.PourEnv` composes.

    Attributes:
        name: the holder's name in :data:`HOLDERS` (``PourEnv(holder=name)``).
        solid: whether the world's containers need collision shapes (an arm touches them).
        obs_names: the names of the inputs the holder adds to the observation.
    """

    name: ClassVar[str]
    solid: ClassVar[bool] = False
    obs_names: tuple[str, ...] = ()

    def reward_weights(self) -> dict[str, float]:
        """The weights of the reward terms the holder adds (:meth:`reward_terms`)."""
        return {}

    def action_space(self) -> spaces.Box:
        """The env's action space: lip velocity (x, y, z) and the tilt action."""
        return spaces.Box(-1.0, 1.0, (4,), np.float32)

    # Whether move() takes the lip and tilt the task commands (else the raw action alone).
    commands_pose: bool = True

    def source_frame(self, gs: ContainerGeometry) -> SourceFrame:
        """How the source is carried (its upright rotation, its lip in its frame)."""
        raise NotImplementedError

    def hold(self, scene: HeldScene, lip: np.ndarray, tilt: float) -> Reached:
        """At reset: take the episode's scene and put the source at ``lip`` and ``tilt``."""
        raise NotImplementedError

    def move(self, a: np.ndarray, commanded: tuple[np.ndarray, float] | None, dt: float) -> Reached:
        """Send the source towards the command for the end of a step of ``dt`` s.

        Args:
            a: the action.
            commanded: the lip (m) and the tilt (deg) the task commands
                (``commands_pose``), else None.
            dt: the step, s.
        """
        raise NotImplementedError

    def failure(self) -> str | None:
        """Why the episode failed at this step, if it did."""
        return None

    def reward_terms(self) -> dict[str, float]:
        """The holder's reward terms, unweighted, by the names of its weights."""
        return {}

    def control_cost(self, a: np.ndarray) -> float:
        """The ``control`` term: -(mean square of the lip velocity actions)."""
        return -float(np.mean(a[:3] ** 2))

    def observation(self) -> np.ndarray | None:
        """The holder's inputs, appended to the task's observation (None: none)."""
        return None

    def info(self) -> dict:
        """The holder's entries of the step's info."""
        return {}

    def camera(self, lip: np.ndarray, target_pos: np.ndarray) -> Camera | None:
        """Where pictures are taken from at this episode (None: the task's camera)."""
        return None

    def drawables(self, sensor: Sensor) -> list[Body]:
        """The holder's body as ``sensor`` draws it, at its current pose (none: nothing).

        Args:
            sensor: the camera drawing it (its :meth:`~pour_gym.sim.sensors.Sensor.mesh`
                simplifies a mesh to about a pixel).
        """
        return []

    def describe(self) -> str:
        """A short description for the env's ``repr``."""
        return self.name


class FreeHolder(Holder):
    """Nothing holds the source: it floats where the action puts it (Pour-v0).

    The source is turned half a turn about the vertical, so that its handle (on +x in a
    container's frame) is away from the target and its lip is the rim point on its -x
    side. It moves kinematically; the fluid moves it smoothly over each step, in as many
    substeps as the motion needs.
    """

    name = "free"

    def source_frame(self, gs: ContainerGeometry) -> SourceFrame:
        """Half a turn about the vertical: the handle away from the target, the lip +x."""
        lip = np.array([gs.rim_center[0] - gs.rim_radius, gs.rim_center[1], gs.height])
        return SourceFrame(about_z(np.pi), lip)

    def hold(self, scene: HeldScene, lip: np.ndarray, tilt: float) -> Reached:
        """Put the source at the lip and tilt (held by nothing)."""
        self._scene = scene
        scene.world.teleport(scene.source, *scene.frame.pose(lip, tilt))
        return Reached(lip, tilt)

    def move(self, a: np.ndarray, commanded: tuple[np.ndarray, float] | None, dt: float) -> Reached:
        """The commanded lip and tilt, reached over the step."""
        lip, tilt = commanded
        scene = self._scene
        scene.world.set_pose(scene.source, *scene.frame.pose(lip, tilt))
        return Reached(lip, tilt)


class PandaHolder(Holder):
    """PourGym/PandaPour-v0: the source container in the gripper of a Franka Panda arm.

    ## Description
    Pour-v0's task, containers, fluid, observations, rewards and reset options, with the
    source held by a Panda (``pybullet_data``'s ``franka_panda/panda.urdf``) standing at
    the table's edge 0.6 m to the side of the source's start (at y = -0.6 m, reaching
    along +y); the source is turned so that its handle faces the arm and its lip the
    target (+x). At reset the source is in the gripper, filled, above the table: a cup held
    by its handle (the fingers across the handle, the hand approaching horizontally), a
    container without a handle pinched on its rim wall from above, on the side away from
    its lip (:func:`pour_gym.sim.panda.grasp`). The container is rigidly attached to the
    hand (its pose is the hand's times the grasp: it cannot slip), and the fluid's
    substeps take its pose from the hand, interpolated over each 0.1 s step. The fluid
    collides with the containers, not with the arm or the fingers (they never reach into
    a cavity).

    The arm moves kinematically: each step its joints go to targets within their limits,
    each at most its velocity limit (2.175 / 2.61 rad/s). The arm, the held container,
    the target and the table collide: the containers have collision shapes (V-HACD convex
    pieces, as the ``bullet`` fluid's), and after every move pybullet is asked whether
    the arm or the held container touches the target or the table. A touch ends the
    episode as a failure, its reason in ``info["failure"]`` (the target is not pushed
    around: the touch that would start knocking it over ends the episode, and the
    contact dynamics at 240 Hz, which would cost about two thirds of a fluid step, are
    not simulated).

    ## Action Space
    ``control="ee"`` (default): as Pour-v0, ``Box(-1, 1, (4,), float32)``: lip velocity
    (x, y, z, times ``max_speed``) and tilt rate (or tilt angle with
    ``tilt_control="angle"``), turned into joint targets by pybullet's inverse kinematics
    with the joint limits and a rest pose (and, where a joint at its limit keeps the arm
    from the pose, a solve with that joint held). What the arm cannot follow (out of reach, a
    joint at its limit, faster than a joint may move) is left undone, never an error:
    ``info["lip_error_m"]`` and ``info["tilt_error_deg"]`` say how far the pose reached
    is from the one commanded, ``info["clipped_joints"]`` how many joints a limit held
    back. The next step starts from the pose reached. ``control="joints"``: ``Box(-1, 1,
    (7,), float32)``, each joint's velocity over its limit.

    ## Observation Space
    Pour-v0's observation (``obs_mode="features"``: the 16 warped features;
    ``"state"``: the 19 raw quantities) with the lip and the tilt as the arm reached them,
    then the 7 joint positions over their ranges (-1 to 1) and the 7 joint velocities over
    their limits (``JOINT_NAMES``): ``Box(-10, 10, (30,))`` or ``(33,)``.

    ## Rewards
    Pour-v0's terms and weights, plus ``joint_limit`` = -(share of the seven joints within
    0.02 rad of a limit) and ``collision`` = -1 on the step the arm or the held container
    touches the target or the table, weighted by ``joint_limit_weight`` and
    ``collision_weight``; ``info["reward_<term>"]`` holds each weighted term. With
    ``control="joints"`` the ``control`` term is -(mean square of the joint actions).

    ## Starting State
    As Pour-v0; the arm's joints from inverse kinematics from its rest pose to the grasp of
    the source at the start (``info["lip_error_m"]`` is its error); where the arm cannot
    take that grasp within 2 mm, the same grasp turned half a turn about the hand's
    approach (the two fingers hold it alike), if the arm takes that one better (the
    docs' environments page gives the scripted policy's success per container).

    ## Episode End
    As Pour-v0, and a touch of the target or the table (a failure).

    ## Arguments
    Every argument of Pour-v0 (:class:`pour_gym.envs.pour.PourEnv`), and:

    | argument | type | default | meaning |
    |---|---|---|---|
    | ``control`` | str | ``"ee"`` | ``"ee"`` (lip and tilt) or ``"joints"`` (joint velocities) |
    | ``joint_limit_weight`` | float | 0.1 | weight of ``joint_limit`` |
    | ``collision_weight`` | float | 1.0 | weight of ``collision`` |

    ``gym.make("PourGym/PandaPour-v0", ...)`` is ``PourEnv(holder="panda", ...)``.

    ## Version History
    * v0 (this release). The arm became a holder that Pour-v0's task composes (it was a
      subclass of it); nothing an episode does changed. The faster fluid kernel (see
      Pour-v0). The grasp turned round where the arm cannot take the container's own at
      the start: the pybullet mug's episodes changed (the scripted policy 1 -> 7 pours in
      10), and those of any container whose start the arm missed by over 2 mm. The
      sensors draw the arm: every ``obs_mode`` (``depth``, ``rgb``, ``points``) is taken.
      Where a joint at its limit kept the arm from a commanded tilt, it now solves with
      that joint held and the other six free (``Panda.solve_held``): episodes change from
      the first step the arm could not follow (the pybullet mug's cup stopped at 81 deg,
      short of its pour; the scripted policy pours every catalogue container now).
    """

    name = "panda"
    solid = True

    def __init__(
        self, control: str = "ee", joint_limit_weight: float = 0.1, collision_weight: float = 1.0
    ):
        if control not in PANDA_CONTROLS:
            raise InputError(f"control must be one of {PANDA_CONTROLS}, not {control!r}")
        self.control = control
        self.weights = {"joint_limit": joint_limit_weight, "collision": collision_weight}
        self.obs_names = JOINT_NAMES
        self._panda: Panda | None = None
        self._grasps: dict[str, Grasp] = {}
        self._held: Grasp | None = None  # the episode's grasp: the container's, or turned
        self._scene: HeldScene | None = None  # the episode's world and containers
        # The arm's links as each camera draws them, by the camera's detail (m a pixel).
        self._drawn: dict[float, list] = {}
        self._q = np.zeros(len(ARM_JOINTS))  # the joints the arm was last set to, rad
        self._qd = np.zeros(len(ARM_JOINTS))
        self._clipped = np.zeros(len(ARM_JOINTS), dtype=bool)
        self._lip_error = 0.0
        self._tilt_error = 0.0
        self._failed: str | None = None

    def reward_weights(self) -> dict[str, float]:
        """``joint_limit`` and ``collision``."""
        return dict(self.weights)

    def action_space(self) -> spaces.Box:
        """Pour-v0's four actions (``"ee"``), or one velocity per joint (``"joints"``)."""
        if self.control == "joints":
            return spaces.Box(-1.0, 1.0, (len(ARM_JOINTS),), np.float32)
        return super().action_space()

    def describe(self) -> str:
        """``panda`` and its control."""
        return f"panda, control={self.control}"

    @property
    def commands_pose(self) -> bool:
        """``control="ee"`` moves by the commanded lip and tilt; ``"joints"`` by the action."""
        return self.control == "ee"

    def panda(self) -> Panda:
        """The arm (loaded into the world's client at the first reset in that world)."""
        client = self._scene.world.client
        if self._panda is None or self._panda.client is not client:
            self._panda = Panda(client)
        return self._panda

    def _grasp(self) -> Grasp:
        """The source's own grasp (kept per container name)."""
        name = self._scene.source_name
        if name not in self._grasps:
            self._grasps[name] = grasp(self._scene.source.asset)
        return self._grasps[name]

    def _hand_goal(self, lip: np.ndarray, tilt: float, g: Grasp | None = None):
        """Where the grasp frame goes for the source's lip at ``lip`` (m), tilted (deg).

        ``g``: the grasp (default: the episode's).
        """
        g = g or self._held
        position, rotation = self._scene.frame.pose(lip, tilt)
        return rotation @ g.position + position, rotation @ g.rotation

    def source_frame(self, gs: ContainerGeometry) -> SourceFrame:
        """A quarter turn about the vertical: the handle faces the arm (-y), the lip +x."""
        lip = np.array([gs.rim_center[0], gs.rim_center[1] + gs.rim_radius, gs.height])
        return SourceFrame(about_z(-np.pi / 2), lip)

    def hold(self, scene: HeldScene, lip: np.ndarray, tilt: float) -> Reached:
        """The arm takes the source at its start: inverse kinematics from the rest pose.

        The container's grasp as :func:`~pour_gym.sim.panda.grasp` gives it; where the
        arm cannot take it there (a pose error over ``REACHED``: the pybullet mug's
        handle put the wrist at its limits 10-36 mm short, and the arm poured in 1 of
        10 episodes), the grasp turned half a turn about the hand's approach, if the arm
        takes that one better.
        """
        self._scene = scene
        panda = self.panda()
        g = self._grasp()
        choices = []
        for held, rests in ((g, REST_POSES), (g.turned(), TURNED_REST_POSES)):
            rest = np.array(rests[g.kind])
            panda.rest = rest
            panda.set_joints(rest, fingers=0.5 * g.width)
            goal = self._hand_goal(lip, tilt, held)
            q = panda.reach(*goal, [rest] + [rest + np.array(d) for d in SEED_OFFSETS])
            error = panda.pose_error(q, *goal)
            missed = error > REACHED
            choices.append((missed, error, held, q, rest))
            if not missed:
                break  # the container's own grasp is kept wherever the arm takes it
        _, _, self._held, self._q, panda.rest = min(choices, key=lambda c: c[:2])
        panda.set_joints(self._q)
        self._qd = np.zeros(len(ARM_JOINTS))
        self._clipped = np.zeros(len(ARM_JOINTS), dtype=bool)
        self._failed = None
        reached = self._follow_hand(teleport=True)
        self._lip_error = float(np.linalg.norm(reached.lip - lip))
        self._tilt_error = abs(reached.tilt)
        return reached

    def _follow_hand(self, teleport: bool = False) -> Reached:
        """Pose the source as the hand holds it; the lip and tilt it then has."""
        g, scene = self._held, self._scene
        hand_position, hand_rotation = self.panda().hand_pose()
        rotation = hand_rotation @ g.rotation.T
        position = hand_position - rotation @ g.position
        if teleport:
            scene.world.teleport(scene.source, position, rotation)
        else:
            scene.world.set_pose(scene.source, position, rotation)
        return scene.frame.lip_tilt(position, rotation)

    def move(self, a: np.ndarray, commanded: tuple[np.ndarray, float] | None, dt: float) -> Reached:
        """Joint targets for the command, reached within the arm's limits; the source follows.

        ``control="ee"``: towards the commanded lip and tilt by inverse kinematics;
        ``"joints"``: the action's joint velocities.
        """
        panda = self.panda()
        q0 = self._q
        if self.control == "ee":
            lip, tilt = commanded
            pose = self._hand_goal(lip, tilt)
            q, self._clipped = panda.follow(*pose, dt)
        else:
            q, self._clipped = panda.limit(q0 + a * panda.max_velocity * dt, dt)
        panda.set_joints(q)
        self._q = q
        self._qd = (q - q0) / dt
        reached = self._follow_hand()
        if self.control == "ee":
            self._lip_error = float(np.linalg.norm(reached.lip - lip))
            self._tilt_error = abs(reached.tilt - tilt)
        else:
            self._lip_error = self._tilt_error = 0.0
        return reached

    def failure(self) -> str | None:
        """A touch of the target or the table by the arm or the held container."""
        scene, panda = self._scene, self.panda()
        client, table = scene.world.client, scene.world.table_body
        source, target = scene.source.body, scene.target.body
        self._failed = None
        if client.getClosestPoints(source, target, 0.0):
            self._failed = "the held container touched the target"
        elif table is not None and client.getClosestPoints(source, table, 0.0):
            self._failed = "the held container hit the table"
        elif panda.touching(target):
            self._failed = "the arm touched the target"
        elif table is not None and panda.touching(table):
            self._failed = "the arm hit the table"
        return self._failed

    def reward_terms(self) -> dict[str, float]:
        """``joint_limit`` and ``collision``, unweighted."""
        return {
            "joint_limit": -float(np.mean(self.panda().at_limit(self._q))),
            "collision": -1.0 if self._failed else 0.0,
        }

    def control_cost(self, a: np.ndarray) -> float:
        """Pour-v0's, or -(mean square of the joint actions) with ``control="joints"``."""
        if self.control == "joints":
            return -float(np.mean(a**2))
        return super().control_cost(a)

    def observation(self) -> np.ndarray:
        """The joints' positions and velocities, normalised (see ``JOINT_NAMES``)."""
        return self.panda().normalised(self._q, self._qd)

    def info(self) -> dict:
        """``failure``, ``lip_error_m``, ``tilt_error_deg``, ``clipped_joints``."""
        return {
            "failure": self._failed or "",
            "lip_error_m": self._lip_error,
            "tilt_error_deg": self._tilt_error,
            "clipped_joints": int(np.count_nonzero(self._clipped)),
        }

    def drawables(self, sensor: Sensor) -> list[Body]:
        """The arm's links (and fingers) at their current poses, as ``sensor`` draws them."""
        panda = self.panda()
        # Every Panda has the same links; the head camera's and the pictures' detail differ.
        key = sensor.cell
        shapes = self._drawn.get(key)
        if shapes is None:
            shapes = [
                (link, *sensor.mesh(mesh), local) for link, mesh, local in panda.visual_meshes()
            ]
            if len(self._drawn) >= 4:  # the picture camera moved: drop the oldest
                self._drawn.pop(next(iter(self._drawn)))
            self._drawn[key] = shapes
        frames = panda.link_frames({link for link, *_ in shapes})
        bodies = []
        for link, vertices, faces, local in shapes:
            pose = frames[link] @ local
            bodies.append(
                Body(vertices, faces, pose[:3, :3], pose[:3, 3], SEGMENTS["arm"], ARM_COLOR)
            )
        return bodies

    def camera(self, lip: np.ndarray, target_pos: np.ndarray) -> Camera:
        """Over the containers, at the arm behind them."""
        mid = 0.5 * (lip + target_pos)
        return Camera(target=(float(mid[0]), -0.12, 0.2), distance=0.8, yaw=150.0, pitch=-22.0)


HOLDERS: dict[str, type[Holder]] = {"free": FreeHolder, "panda": PandaHolder}


def make_holder(name: str, **kwargs) -> Holder:
    """A holder by name, with its arguments.

    Raises:
        InputError: an unknown holder, or arguments it does not take (named).
    """
    if name not in HOLDERS:
        raise InputError(f"holder must be one of {', '.join(HOLDERS)}, not {name!r}")
    cls = HOLDERS[name]
    takes = set(inspect.signature(cls).parameters)
    unknown = sorted(set(kwargs) - takes)
    if unknown:
        raise InputError(
            f"unknown argument(s) {', '.join(unknown)}: neither the pouring task's nor the "
            f"{name!r} holder's ({cls.__name__} takes {', '.join(sorted(takes)) or 'none'})"
        )
    return cls(**kwargs)
