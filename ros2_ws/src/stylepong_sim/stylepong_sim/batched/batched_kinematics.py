"""Batched kinematics and rigid-body dynamics of the one UR5 + paddle model, in torch.

Everything here works on N robots at once, on cpu or cuda alike, and is built from
`stylepong_description.robot_model` (Pinocchio's joint placements, axes and link inertias; the link
collision meshes of MuJoCo's import of the same URDF), so the batched training world moves the same
arm as the MuJoCo cell.

Layout: the environment axis is LAST (a vector is [3, N], a rotation [3, 3, N], per-joint data
[..., 6, N]). With N contiguous, every small 3x3 or 6x6 product becomes a few long, vectorised
elementwise operations; with N first, torch spends its time on the tiny trailing axes (measured 3-4x
slower on this CPU).

Dynamics use spatial vectors in world orientation about the robot base's origin (Featherstone's
notation, angular part first). In that frame a joint's motion axis S_j = (z_j, o_j x z_j) is fixed to
its parent body, so body velocities, bias accelerations and composite inertias are prefix and suffix
sums along the joint axis: no loop over links, exact agreement with Pinocchio's CRBA and RNEA.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import torch

from stylepong_description import robot_model
from stylepong_sim import world_spec

NUM_JOINTS = robot_model.NUM_JOINTS
LINK_BODIES = ('shoulder_link', 'upper_arm_link', 'forearm_link', 'wrist_1_link', 'wrist_2_link', 'wrist_3_link')


# --- Small products on the leading axes (the environment axis and any others trail) ------------------
def cross(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """a x b over the FIRST axis (length 3)."""
    return torch.stack((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


def dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """a . b over the first axis (length 3)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def mat_vec(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """m v for m [3, 3, ...] and v [3, ...]."""
    return m[:, 0] * v[0] + m[:, 1] * v[1] + m[:, 2] * v[2]


def mat_t_vec(m: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """m^T v for m [3, 3, ...] and v [3, ...]."""
    return m[0] * v[0] + m[1] * v[1] + m[2] * v[2]


def mat_mat(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """a b for [3, 3, ...] matrices."""
    return a[:, 0, None] * b[None, 0] + a[:, 1, None] * b[None, 1] + a[:, 2, None] * b[None, 2]


# --- The model as tensors ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Capsule:
    """A segment a-b with a radius, fixed in the frame of joint `joint` (0-based); metres."""

    joint: int
    a_m: tuple[float, float, float]
    b_m: tuple[float, float, float]
    radius_m: float
    name: str


@dataclass(frozen=True)
class ArmModel:
    """The UR5 + paddle as constant tensors (URDF joint order; lengths m, masses kg, angles rad).

    Joint i's frame relative to its parent's at angle q is R = A_i + sin(q) B_i + (1 - cos q) C_i
    (Rodrigues' formula with the fixed placement folded in), with origin `joint_origin_m[:, i]`.
    A link's inertia about its centre of mass is Q diag(moments) Q^T in its joint frame.
    """

    rot_a: torch.Tensor  # [3, 3, 6, 1]
    rot_b: torch.Tensor  # [3, 3, 6, 1]
    rot_c: torch.Tensor  # [3, 3, 6, 1]
    joint_origin_m: torch.Tensor  # [3, 6] in the parent joint's frame (the first: in the base frame)
    axis: torch.Tensor  # [3, 6] each joint's axis in its own frame
    base_rot: torch.Tensor  # [3, 3] robot base orientation in the world
    base_pos_m: torch.Tensor  # [3] robot base origin in the world
    mass_kg: torch.Tensor  # [6, 1] link masses (the paddle is part of the last)
    com_m: torch.Tensor  # [3, 6, 1] centres of mass, joint frames
    inertia_axes: torch.Tensor  # [3, 3, 6, 1] principal axes Q (columns), joint frames
    inertia_moments: torch.Tensor  # [3, 6, 1] principal moments, kg m^2
    paddle_rot: torch.Tensor  # [3, 3, 1] paddle_centre frame in the last joint's frame
    paddle_pos_m: torch.Tensor  # [3, 1]
    capsule_joint: torch.Tensor  # [L] long: the joint frame each collision capsule is fixed in
    capsule_a_m: torch.Tensor  # [3, L, 1]
    capsule_b_m: torch.Tensor  # [3, L, 1]
    capsule_radius_m: torch.Tensor  # [L, 1]
    capsule_joints: tuple[int, ...]  # capsule_joint as Python ints (no device round trip per step)
    lower_rad: torch.Tensor  # [6, 1]
    upper_rad: torch.Tensor  # [6, 1]
    velocity_limit_rad_s: torch.Tensor  # [6, 1]
    effort_limit_nm: torch.Tensor  # [6, 1]


_AXES = {'JointModelRX': (1.0, 0.0, 0.0), 'JointModelRY': (0.0, 1.0, 0.0), 'JointModelRZ': (0.0, 0.0, 1.0)}


def _joint_axis(joint) -> np.ndarray:
    name = joint.shortname()
    if name in _AXES:
        return np.array(_AXES[name])
    if name == 'JointModelRevoluteUnaligned':
        return np.asarray(joint.axis, dtype=float)
    raise ValueError(f'the batched world handles revolute joints only, not {name}')


def _fit_capsule(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule enclosing a mesh's vertices: segment on the principal axis, radius = farthest vertex
    from that axis, ends pulled in as far as the half-sphere caps still cover every vertex."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    axis = vt[0]
    along = (points - centre) @ axis
    radial = np.linalg.norm((points - centre) - np.outer(along, axis), axis=1)
    radius = float(radial.max())
    reach = np.sqrt(np.maximum(radius**2 - radial**2, 0.0))  # how far past an end a vertex may be
    hi = float((along - reach).max())
    lo = float((along + reach).min())
    if lo > hi:  # short and fat: a sphere around the middle
        middle = centre + 0.5 * (along.min() + along.max()) * axis
        return middle, middle, float(np.linalg.norm(points - middle, axis=1).max())
    return centre + lo * axis, centre + hi * axis, radius


def _quat_to_matrix(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@functools.lru_cache(maxsize=1)
def link_capsules() -> tuple[Capsule, ...]:
    """Collision capsules of the arm links (fitted to MuJoCo's collision meshes) and the paddle handle.

    A URDF link's frame is its joint's frame, so each capsule is given in its joint's frame. The blade
    is not among them: the world treats it exactly, as a disc.
    """
    import mujoco

    mj = robot_model.mujoco_model()
    capsules = []
    for joint, body in enumerate(LINK_BODIES):
        body_id = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, body)
        points = []
        for geom in range(mj.ngeom):
            if mj.geom_bodyid[geom] != body_id or mj.geom_type[geom] != mujoco.mjtGeom.mjGEOM_MESH:
                continue
            mesh = mj.geom_dataid[geom]
            start, count = mj.mesh_vertadr[mesh], mj.mesh_vertnum[mesh]
            vertices = mj.mesh_vert[start : start + count].astype(float)
            points.append(vertices @ _quat_to_matrix(mj.geom_quat[geom]).T + mj.geom_pos[geom])
        if points:
            a, b, radius = _fit_capsule(np.concatenate(points))
            capsules.append(Capsule(joint, tuple(a), tuple(b), radius, body))
    # The handle: from the paddle body's origin (tool0) along its z axis, in the last joint's frame.
    model = robot_model.pinocchio_model()
    placement = model.frames[model.getFrameId(robot_model.PADDLE_BODY)].placement
    a = placement.translation
    b = a + placement.rotation @ np.array([0.0, 0.0, robot_model.PADDLE.handle_length_m])
    capsules.append(Capsule(NUM_JOINTS - 1, tuple(a), tuple(b), robot_model.PADDLE.handle_radius_m, 'paddle_handle'))
    return tuple(capsules)


def build_arm_model(device: str | torch.device = 'cpu', dtype: torch.dtype = torch.float32) -> ArmModel:
    """Read the one robot model into tensors on `device` (the base placement from the world spec)."""
    model = robot_model.pinocchio_model()
    rot_a, rot_b, rot_c, origins, axes, masses, coms, inertia_axes, moments = ([] for _ in range(9))
    for i in range(1, NUM_JOINTS + 1):
        placement = model.jointPlacements[i]
        axis = _joint_axis(model.joints[i])
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        rot_a.append(placement.rotation)
        rot_b.append(placement.rotation @ k)
        rot_c.append(placement.rotation @ k @ k)
        origins.append(placement.translation)
        axes.append(axis)
        inertia = model.inertias[i]
        masses.append(inertia.mass)
        coms.append(inertia.lever)
        values, vectors = np.linalg.eigh(inertia.inertia)
        moments.append(values)
        inertia_axes.append(vectors)
    paddle = model.frames[model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)]
    if paddle.parentJoint != NUM_JOINTS:
        raise RuntimeError('the paddle centre must hang on the last joint')
    capsules = link_capsules()
    limits = robot_model.joint_limits()
    base_rot, base_pos_m = world_spec.robot_base_pose()

    def t(x) -> torch.Tensor:
        return torch.as_tensor(np.asarray(x, dtype=float), dtype=dtype, device=device)

    def per_joint_matrices(ms) -> torch.Tensor:  # list of 6 [3, 3] -> [3, 3, 6, 1]
        return t(np.stack(ms, axis=-1))[..., None]

    return ArmModel(
        rot_a=per_joint_matrices(rot_a),
        rot_b=per_joint_matrices(rot_b),
        rot_c=per_joint_matrices(rot_c),
        joint_origin_m=t(np.stack(origins, axis=-1)),
        axis=t(np.stack(axes, axis=-1)),
        base_rot=t(base_rot),
        base_pos_m=t(base_pos_m),
        mass_kg=t(masses)[:, None],
        com_m=t(np.stack(coms, axis=-1))[..., None],
        inertia_axes=per_joint_matrices(inertia_axes),
        inertia_moments=t(np.stack(moments, axis=-1))[..., None],
        paddle_rot=t(paddle.placement.rotation)[..., None],
        paddle_pos_m=t(paddle.placement.translation)[:, None],
        capsule_joint=torch.tensor([c.joint for c in capsules], dtype=torch.long, device=device),
        capsule_a_m=t(np.stack([c.a_m for c in capsules], axis=-1))[..., None],
        capsule_b_m=t(np.stack([c.b_m for c in capsules], axis=-1))[..., None],
        capsule_radius_m=t([c.radius_m for c in capsules])[:, None],
        capsule_joints=tuple(c.joint for c in capsules),
        lower_rad=t(limits.lower_rad)[:, None],
        upper_rad=t(limits.upper_rad)[:, None],
        velocity_limit_rad_s=t(limits.velocity_rad_s)[:, None],
        effort_limit_nm=t(limits.effort_nm)[:, None],
    )


# --- Kinematics -----------------------------------------------------------------------------------------
@dataclass
class Kinematics:
    """World poses of the joint frames and of the paddle centre, for N configurations."""

    rot: torch.Tensor  # [3, 3, 6, N] joint frame orientations
    origin_m: torch.Tensor  # [3, 6, N] joint frame origins
    axis: torch.Tensor  # [3, 6, N] joint axes (unit)
    paddle_rot: torch.Tensor  # [3, 3, N] columns: paddle_centre x, y, z (z = the blade's face normal)
    paddle_pos_m: torch.Tensor  # [3, N] blade centre


def forward_kinematics(model: ArmModel, q_rad: torch.Tensor) -> Kinematics:
    """Joint frames and the paddle centre in the world for joint positions q [6, N]."""
    local = model.rot_a + torch.sin(q_rad) * model.rot_b + (1.0 - torch.cos(q_rad)) * model.rot_c
    n = q_rad.shape[-1]
    rot = model.base_rot[..., None].expand(3, 3, n)
    pos = model.base_pos_m[:, None].expand(3, n)
    rots, origins = [], []
    for i in range(NUM_JOINTS):
        pos = pos + mat_vec(rot, model.joint_origin_m[:, i, None])
        rot = mat_mat(rot, local[:, :, i])
        rots.append(rot)
        origins.append(pos)
    rot_all = torch.stack(rots, dim=2)
    axis = mat_vec(rot_all, model.axis[..., None])
    return Kinematics(
        rot=rot_all,
        origin_m=torch.stack(origins, dim=1),
        axis=axis,
        paddle_rot=mat_mat(rot, model.paddle_rot),
        paddle_pos_m=pos + mat_vec(rot, model.paddle_pos_m),
    )


def capsule_segments(model: ArmModel, kin: Kinematics) -> tuple[torch.Tensor, torch.Tensor]:
    """World end points [3, L, N] of every collision capsule."""
    joints = list(model.capsule_joints)
    if joints[:NUM_JOINTS] == list(range(NUM_JOINTS)):
        # One capsule per link in joint order, then extras: whole-tensor products and views, no gather
        # (an index gather of the rotations costs more than all the products together).
        ends = []
        for local in (model.capsule_a_m, model.capsule_b_m):
            parts = [kin.origin_m + mat_vec(kin.rot, local[:, :NUM_JOINTS])]
            for c, j in enumerate(joints[NUM_JOINTS:], start=NUM_JOINTS):
                parts.append((kin.origin_m[:, j] + mat_vec(kin.rot[:, :, j], local[:, c]))[:, None])
            ends.append(torch.cat(parts, dim=1))
        return ends[0], ends[1]
    rot = kin.rot[:, :, model.capsule_joint]  # [3, 3, L, N]
    origin = kin.origin_m[:, model.capsule_joint]  # [3, L, N]
    return origin + mat_vec(rot, model.capsule_a_m), origin + mat_vec(rot, model.capsule_b_m)


# --- Dynamics -------------------------------------------------------------------------------------------
@dataclass
class Spatial:
    """Per-link world-frame quantities (about the base origin) shared by M(q) and the bias torques."""

    axis: torch.Tensor  # [3, 6, N] angular part of S_j
    axis_moment: torch.Tensor  # [3, 6, N] linear part of S_j: o_j x z_j
    mass: torch.Tensor  # [6, 1]
    com: torch.Tensor  # [3, 6, N]
    principal: torch.Tensor  # [3, 3, 6, N] principal axes of each link's inertia, world orientation
    moments: torch.Tensor  # [3, 6, 1]


def spatial(model: ArmModel, kin: Kinematics) -> Spatial:
    """The links' Spatial quantities for the given kinematics, about the base origin."""
    origin = kin.origin_m - model.base_pos_m[:, None, None]  # small lever arms keep float32 exact
    return Spatial(
        axis=kin.axis,
        axis_moment=cross(origin, kin.axis),
        mass=model.mass_kg,
        com=origin + mat_vec(kin.rot, model.com_m),
        principal=mat_mat(kin.rot, model.inertia_axes),
        moments=model.inertia_moments,
    )


def _rotational_inertia_times(sp: Spatial, w: torch.Tensor) -> torch.Tensor:
    """I_c w for each link (inertia about its centre of mass, world orientation); w [3, 6, N]."""
    return mat_vec(sp.principal, sp.moments * mat_t_vec(sp.principal, w))


def _inertia_times(sp: Spatial, w: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The links' spatial inertias applied to motions (w, v) [3, 6, N]: momentum (about the origin, linear).

    For a link of mass m, centre c and central inertia I_c: p = m (v + w x c), L = I_c w + c x p.
    """
    p = sp.mass * (v + cross(w, sp.com))
    return _rotational_inertia_times(sp, w) + cross(sp.com, p), p


def mass_matrix(sp: Spatial) -> torch.Tensor:
    """Joint-space inertia M(q) [6, 6, N] by the composite-rigid-body algorithm.

    The links from joint i outwards form a composite body of mass m_i, first moment h_i and
    rotational inertia J_i about the origin; its spatial inertia maps S_i to F_i = (J_i z_i + h_i x u_i,
    m_i u_i + z_i x h_i), and M_ij = F_i . S_j for j <= i.
    """
    z, u = sp.axis, sp.axis_moment
    c = sp.com
    p = sp.principal
    # Central inertia P diag(moments) P^T plus the parallel-axis term m (|c|^2 1 - c c^T).
    weighted = p * sp.moments[None]
    inertia = (
        weighted[:, 0, None] * p[None, :, 0]
        + weighted[:, 1, None] * p[None, :, 1]
        + weighted[:, 2, None] * p[None, :, 2]
    )
    mc = sp.mass * c
    inertia = inertia - mc[:, None] * c[None, :]
    inertia = inertia + _eye_like(inertia) * dot(mc, c)
    composite_inertia = suffix_sum(inertia)
    composite_moment = suffix_sum(mc)
    composite_mass = suffix_sum(sp.mass)
    f_ang = mat_vec(composite_inertia, z) + cross(composite_moment, u)
    f_lin = composite_mass * u + cross(z, composite_moment)
    products = dot(f_ang[:, :, None], z[:, None]) + dot(f_lin[:, :, None], u[:, None])  # [6i, 6j, N]
    return torch.where(_LOWER_TRIANGLE.to(products.device), products, products.transpose(0, 1))


_LOWER_TRIANGLE = torch.tril(torch.ones(NUM_JOINTS, NUM_JOINTS, dtype=torch.bool))[..., None]


def _eye_like(m: torch.Tensor) -> torch.Tensor:
    """The 3x3 identity shaped to broadcast against m [3, 3, ...]."""
    return torch.eye(3, dtype=m.dtype, device=m.device).reshape(3, 3, *([1] * (m.dim() - 2)))


_PREFIX = torch.tril(torch.ones(NUM_JOINTS, NUM_JOINTS))
_SUFFIX = torch.triu(torch.ones(NUM_JOINTS, NUM_JOINTS))


def prefix_sum(x: torch.Tensor) -> torch.Tensor:
    """Sum up to each joint along the joint axis (second to last): a 6x6 matmul, faster than cumsum."""
    return _PREFIX.to(x.device, x.dtype) @ x


def suffix_sum(x: torch.Tensor) -> torch.Tensor:
    """Sum from each joint outwards along the joint axis (second to last)."""
    return _SUFFIX.to(x.device, x.dtype) @ x


def bias_torques(sp: Spatial, qd_rad_s: torch.Tensor, gravity_m_s2: torch.Tensor | float = 0.0) -> torch.Tensor:
    """C(q, qd) qd + g(q) [6, N]: the recursive Newton-Euler torques at zero joint acceleration.

    gravity_m_s2: gravity's magnitude along -z (float or [N]); 0 gives the velocity terms alone.
    """
    z, u = sp.axis, sp.axis_moment
    w = prefix_sum(z * qd_rad_s)  # body spatial velocities (w, v)
    v = prefix_sum(u * qd_rad_s)
    w_parent = torch.cat((torch.zeros_like(w[:, :1]), w[:, :-1]), dim=1)
    v_parent = torch.cat((torch.zeros_like(v[:, :1]), v[:, :-1]), dim=1)
    # S_j moves with its parent: dS_j/dt = v_parent x S_j (spatial motion cross product).
    aw = prefix_sum(qd_rad_s * cross(w_parent, z))
    av = prefix_sum(qd_rad_s * (cross(w_parent, u) + cross(v_parent, z)))
    if not (isinstance(gravity_m_s2, float) and gravity_m_s2 == 0.0):
        # The base accelerating upwards at g stands for gravity acting on every link.
        av = av + torch.stack(
            (
                torch.zeros_like(av[0]),
                torch.zeros_like(av[0]),
                torch.as_tensor(gravity_m_s2, dtype=av.dtype, device=av.device).expand_as(av[0]),
            )
        )
    hn, hf = _inertia_times(sp, w, v)  # momentum
    fn, ff = _inertia_times(sp, aw, av)
    fn = fn + cross(w, hn) + cross(v, hf)  # + v x* (I v)
    ff = ff + cross(w, hf)
    fn = suffix_sum(fn)
    ff = suffix_sum(ff)
    return dot(z, fn) + dot(u, ff)
