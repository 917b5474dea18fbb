"""PourGym/PandaPour-v0: Pour-v0 with a Franka Panda arm holding the source container."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from scipy.spatial.transform import Rotation

from pour_gym.envs.pour import OBS_LIMIT, PourEnv
from pour_gym.sim import Camera
from pour_gym.sim.panda import ARM_JOINTS, REST_POSES, SEED_OFFSETS, Grasp, Panda, grasp

CONTROLS = ("ee", "joints")
JOINT_NAMES = tuple(f"joint{j + 1}_position" for j in ARM_JOINTS) + tuple(
    f"joint{j + 1}_velocity" for j in ARM_JOINTS
)


class PandaPourEnv(PourEnv):
    """Pour-v0 with the source container in the gripper of a Franka Panda arm.

    ## Description
    Pour-v0's task, containers, fluid, observations, rewards and reset options, with the
    source held by a Panda (``pybullet_data``'s ``franka_panda/panda.urdf``) standing at
    the table's edge 0.6 m to the side of the source's start (at y = -0.6 m, reaching
    along +y); the source is turned so that its handle faces the arm and its lip the
    target (+x). At reset the source is in the gripper, filled, above the table: a cup held
    by its handle (the fingers across the handle, the hand approaching horizontally), a
    container without a handle pinched on its rim wall from above, on the side away from
    its lip (:func:`pour_gym.sim.panda.grasp`). The container is rigidly attached to the hand (its
    pose is the hand's times the grasp: it cannot slip), and the fluid's substeps take
    its pose from the hand, interpolated over each 0.1 s step. The fluid collides with the
    containers, not with the arm or the fingers (they never reach into a cavity).

    The arm moves kinematically: each step its joints go to targets within their limits,
    each at most its velocity limit (2.175 / 2.61 rad/s). The arm, the held container,
    the target and the table collide: the containers have collision shapes (V-HACD convex
    pieces, as the ``bullet`` fluid's), and after every move pybullet is asked whether
    the arm or the held container touches the target or the table. A touch ends the
    episode as a failure, its reason in ``info["failure"]`` (the target is not pushed
    around: simulating the contact dynamics at 240 Hz costs 2.9 ms a step, two thirds of
    the fluid's, so the touch that would start knocking it over ends the episode).

    ## Action Space
    ``control="ee"`` (default): as Pour-v0, ``Box(-1, 1, (4,), float32)``: lip velocity
    (x, y, z, times ``max_speed``) and tilt rate (or tilt angle with
    ``tilt_control="angle"``), turned into joint targets by pybullet's inverse kinematics
    with the joint limits and a rest pose. What the arm cannot follow (out of reach, a
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
    the source at the start (``info["lip_error_m"]`` is its error: at most 4.2 mm over the
    catalogue's sources in five seeds each, under 0.01 mm for the bowls, the very small cup
    and the YCB mug; 19 mm for the pybullet mug, whose handle the arm holds badly).

    ## Episode End
    As Pour-v0, and a touch of the target or the table (a failure).

    ## Arguments
    Every argument of Pour-v0 (:class:`pour_gym.envs.pour.PourEnv`), and:

    | argument | type | default | meaning |
    |---|---|---|---|
    | ``control`` | str | ``"ee"`` | ``"ee"`` (lip and tilt) or ``"joints"`` (joint velocities) |
    | ``joint_limit_weight`` | float | 0.1 | weight of ``joint_limit`` |
    | ``collision_weight`` | float | 1.0 | weight of ``collision`` |

    ## Version History
    * v0 (this release).
    """

    solid = True

    def __init__(
        self,
        control: str = "ee",
        joint_limit_weight: float = 0.1,
        collision_weight: float = 1.0,
        **kwargs,
    ):
        if control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, not {control!r}")
        super().__init__(**kwargs)
        EzPickle.__init__(
            self,
            control=control,
            joint_limit_weight=joint_limit_weight,
            collision_weight=collision_weight,
            **kwargs,
        )
        self._add_reward_weights({"joint_limit": joint_limit_weight, "collision": collision_weight})
        self.control = control
        self.obs_names = self.obs_names + JOINT_NAMES
        n = len(self.obs_names)
        self.observation_space = spaces.Box(-OBS_LIMIT, OBS_LIMIT, (n,), np.float32)
        if control == "joints":
            self.action_space = spaces.Box(-1.0, 1.0, (len(ARM_JOINTS),), np.float32)
        self._panda: Panda | None = None
        self._grasps: dict[str, Grasp] = {}
        self._q = np.zeros(len(ARM_JOINTS))  # the joints the arm was last set to, rad
        self._qd = np.zeros(len(ARM_JOINTS))
        self._clipped = np.zeros(len(ARM_JOINTS), dtype=bool)
        self._lip_error = 0.0
        self._tilt_error = 0.0
        self._failed: str | None = None

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode with the source in the gripper (options as Pour-v0)."""
        obs, info = super().reset(seed=seed, options=options)
        # The camera looks over the containers at the arm behind them.
        mid = 0.5 * (self.lip + self.target_pos)
        self.camera = Camera(
            target=(float(mid[0]), -0.12, 0.2), distance=0.8, yaw=150.0, pitch=-22.0
        )
        return obs, info

    @property
    def panda(self) -> Panda:
        """The arm (loaded into the world's client at the first reset)."""
        if self._panda is None or self._panda.client is not self.world.client:
            self._panda = Panda(self.world.client)
        return self._panda

    def _grasp(self) -> Grasp:
        name = self._names["source"]
        if name not in self._grasps:
            self._grasps[name] = grasp(self.source.asset)
        return self._grasps[name]

    def _hand_goal(self, lip: np.ndarray, tilt: float) -> tuple[np.ndarray, np.ndarray]:
        """Where the grasp frame goes for the source's lip at ``lip`` (m), tilted (deg)."""
        g = self._grasp()
        position, rotation = self.source_pose(lip, tilt)
        return rotation @ g.position + position, rotation @ g.rotation

    def _source_frame(self, gs) -> tuple[np.ndarray, np.ndarray]:
        """A quarter turn about the vertical: the handle faces the arm (-y), the lip +x."""
        rotation = Rotation.from_euler("z", -np.pi / 2).as_matrix()
        return rotation, np.array([gs.rim_center[0], gs.rim_center[1] + gs.rim_radius, gs.height])

    def _hold_source(self) -> None:
        """The arm takes the source at its start: inverse kinematics from the rest pose."""
        panda = self.panda
        g = self._grasp()
        panda.rest = np.array(REST_POSES[g.kind])
        panda.set_joints(panda.rest, fingers=0.5 * g.width)
        goal = self._hand_goal(self.lip, self.tilt)
        seeds = [panda.rest] + [panda.rest + np.array(d) for d in SEED_OFFSETS]
        self._q = panda.reach(*goal, seeds)
        panda.set_joints(self._q)
        self._qd = np.zeros(len(ARM_JOINTS))
        self._clipped = np.zeros(len(ARM_JOINTS), dtype=bool)
        self._failed = None
        commanded = self.lip.copy()
        self._follow_hand(teleport=True)
        self._lip_error = float(np.linalg.norm(self.lip - commanded))
        self._tilt_error = abs(self.tilt)

    def _follow_hand(self, teleport: bool = False) -> None:
        """Pose the source as the hand holds it; the lip and tilt are then what it reached."""
        g = self._grasp()
        hand_position, hand_rotation = self.panda.hand_pose()
        rotation = hand_rotation @ g.rotation.T
        position = hand_position - rotation @ g.position
        if teleport:
            self.world.teleport(self.source, position, rotation)
        else:
            self.world.set_pose(self.source, position, rotation)
        self.lip = rotation @ self._lip_local + position
        # Pour-v0 tilts about y: the container's axis is (sin tilt, 0, cos tilt).
        self.tilt = float(np.degrees(np.arctan2(rotation[0, 2], rotation[2, 2])))

    def _move_source(self, a: np.ndarray) -> None:
        """Joint targets for the action, reached within the arm's limits; the source follows."""
        panda = self.panda
        q0 = self._q
        if self.control == "ee":
            lip, tilt = self.commanded(a)
            pose = self._hand_goal(lip, tilt)
            q, self._clipped = panda.follow(*pose, self.dt)
        else:
            q, self._clipped = panda.limit(q0 + a * panda.max_velocity * self.dt, self.dt)
        panda.set_joints(q)
        self._q = q
        self._qd = (q - q0) / self.dt
        self._follow_hand()
        if self.control == "ee":
            self._lip_error = float(np.linalg.norm(self.lip - lip))
            self._tilt_error = abs(self.tilt - tilt)
        else:
            self._lip_error = self._tilt_error = 0.0

    def _failure(self) -> str | None:
        """A touch of the target or the table by the arm or the held container."""
        client, panda = self.world.client, self.panda
        table = self.world.table_body
        source, target = self.source.body, self.target.body
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

    def _extra_terms(self) -> dict[str, float]:
        return {
            "joint_limit": -float(np.mean(self.panda.at_limit(self._q))),
            "collision": -1.0 if self._failed else 0.0,
        }

    def _control_cost(self, a: np.ndarray) -> float:
        if self.control == "joints":
            return -float(np.mean(a**2))
        return super()._control_cost(a)

    def observe(self, obs_mode: str) -> np.ndarray:
        """Pour-v0's observation in either mode, then the joints (see ``JOINT_NAMES``)."""
        arm = self.panda.normalised(self._q, self._qd)
        arm = np.clip(arm, -OBS_LIMIT, OBS_LIMIT).astype(np.float32)
        return np.concatenate([super().observe(obs_mode), arm])

    def _info(self, terms: dict | None = None, success: bool = False) -> dict:
        info = super()._info(terms, success)
        info.update(
            {
                "failure": self._failed or "",
                "lip_error_m": self._lip_error,
                "tilt_error_deg": self._tilt_error,
                "clipped_joints": int(np.count_nonzero(self._clipped)),
            }
        )
        return info

    def __repr__(self) -> str:
        return (
            f"PandaPourEnv(sources={self.sources}, targets={self.targets}, "
            f"obs_mode={self.obs_mode}, control={self.control})"
        )
