"""Incoming balls for the batched world, drawn from the world spec's distribution in torch.

`world_spec.sample_incoming_ball` draws one ball at a time (a bisection over full flight simulations,
tens of milliseconds per ball in numpy). Training resets dozens of environments every policy step, so
this module draws the same distribution for thousands of candidates at once:

* the same uniform draws of launch point, first-bounce point and speed (`IncomingBallDistribution`);
* the same aim: heading at the bounce point, elevation in [-30, 45] degrees such that the flight with
  drag lands on the bounce point, no ball when that bracket does not contain the distance;
* the same rejection of trajectories whose clearance over the net is below the distribution's minimum,
  and of those whose rebound (nominal table coefficients) misses the paddle's reachable region.

Flights are integrated with classic Runge-Kutta in the vertical plane of the heading (drag makes the
motion planar), and the elevation is found with the Illinois variant of regula falsi, which keeps the
bracket like the reference bisection but needs far fewer flights. Crossings of the table plane and
of the net are interpolated with cubic Hermite polynomials, so the solution is more exact than the
reference's 2 ms Euler flights (they differ by a few millimetres at the bounce point).
Balls are kept in a bank refilled in batches; the whole stream is reproducible from the generator.
"""

from __future__ import annotations

import math

import torch

from stylepong_sim import world_spec

MIN_ELEVATION_RAD, MAX_ELEVATION_RAD = world_spec.AIM_ELEVATION_RANGE_RAD
FLIGHT_DT_S = 0.04  # RK4 + Hermite crossings: within 1 um of a 1 ms flight
ILLINOIS_ITERATIONS = 16  # at most; stops once all land within 1 um


def _hermite(y0, y1, d0, d1, tau, dt):
    """Cubic Hermite interpolation between two samples (values y, derivatives d) at fraction tau."""
    t2, t3 = tau * tau, tau * tau * tau
    return (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + tau) * dt * d0 + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * dt * d1


def _hermite_slope(y0, y1, d0, d1, tau, dt):
    """Derivative of `_hermite` with respect to the fraction tau."""
    t2 = tau * tau
    return (
        (6 * t2 - 6 * tau) * y0
        + (3 * t2 - 4 * tau + 1) * dt * d0
        + (-6 * t2 + 6 * tau) * y1
        + (3 * t2 - 2 * tau) * dt * d1
    )


def _crossing_fraction(y0, y1, d0, d1, level, dt):
    """Fraction of the step where the Hermite cubic through (y0, d0), (y1, d1) reaches `level`."""
    tau = ((y0 - level) / (y0 - y1)).clamp(0.0, 1.0)
    for _ in range(3):  # Newton from the linear guess; the cubic is nearly linear over one step
        slope = _hermite_slope(y0, y1, d0, d1, tau, dt)
        tau = (tau - (_hermite(y0, y1, d0, d1, tau, dt) - level) / slope).clamp(0.0, 1.0)
    return tau


def _rk4_flight_step(s, z, vs, vz, dt: float, drag_k_per_m, gravity_m_s2):
    """One RK4 step of a drag-and-gravity flight in the vertical plane of its heading.

    (s, z): distance along the heading and height (m); (vs, vz) their rates (m/s). Tensors, any shape.
    """

    def accel(us, uz):
        speed = torch.sqrt(us * us + uz * uz)
        return -drag_k_per_m * speed * us, -gravity_m_s2 - drag_k_per_m * speed * uz

    a1s, a1z = accel(vs, vz)
    a2s, a2z = accel(vs + 0.5 * dt * a1s, vz + 0.5 * dt * a1z)
    a3s, a3z = accel(vs + 0.5 * dt * a2s, vz + 0.5 * dt * a2z)
    a4s, a4z = accel(vs + dt * a3s, vz + dt * a3z)
    s1 = s + dt * (vs + dt / 6.0 * (a1s + a2s + a3s))
    z1 = z + dt * (vz + dt / 6.0 * (a1z + a2z + a3z))
    vs1 = vs + dt / 6.0 * (a1s + 2 * a2s + 2 * a3s + a4s)
    vz1 = vz + dt / 6.0 * (a1z + 2 * a2z + 2 * a3z + a4z)
    return s1, z1, vs1, vz1


def planar_flight(
    height_m: torch.Tensor,
    speed_m_s: torch.Tensor,
    elevation_rad: torch.Tensor,
    net_distance_m: torch.Tensor,
    gravity_m_s2: float = world_spec.GRAVITY_M_S2,
    drag_k_per_m: float = world_spec.DRAG_K_PER_M,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Fly balls in their vertical plane until the ball's bottom reaches the table.

    height_m: launch height of the ball centre above the contact level (table + radius);
    net_distance_m: horizontal distance to the net plane along the heading.
    Returns (horizontal distance at the table contact, clearance of the ball's bottom over the net's top
    where it crosses the net plane (+inf if it lands before the net), horizontal and vertical velocity
    at the contact). Balls that never land within world_spec.MAX_FLIGHT_S get +inf distance.
    """
    s = torch.zeros_like(height_m)
    z = height_m.clone()
    vs = speed_m_s * torch.cos(elevation_rad)
    vz = speed_m_s * torch.sin(elevation_rad)
    landing = torch.full_like(s, math.inf)
    landing_vs = torch.zeros_like(s)
    landing_vz = torch.zeros_like(s)
    clearance = torch.full_like(s, math.inf)
    active = torch.ones_like(s, dtype=torch.bool)
    # Heights are of the ball centre above (table + radius), i.e. of the ball's bottom above the table.
    net_top = world_spec.NET_HEIGHT_M
    dt = FLIGHT_DT_S

    for step in range(int(world_spec.MAX_FLIGHT_S / dt)):
        s1, z1, vs1, vz1 = _rk4_flight_step(s, z, vs, vz, dt, drag_k_per_m, gravity_m_s2)
        crosses_net = active & (s < net_distance_m) & (s1 >= net_distance_m)
        if bool(crosses_net.any()):
            tau = _crossing_fraction(s, s1, vs, vs1, net_distance_m, dt)
            z_net = _hermite(z, z1, vz, vz1, tau, dt)
            clearance = torch.where(crosses_net, z_net - net_top, clearance)
        lands = active & (z1 <= 0.0) & (z > 0.0)
        if bool(lands.any()):
            tau = _crossing_fraction(z, z1, vz, vz1, torch.zeros_like(z), dt)
            landing = torch.where(lands, _hermite(s, s1, vs, vs1, tau, dt), landing)
            # Velocities are near-linear over a step (drag changes them slowly): interpolate linearly.
            landing_vs = torch.where(lands, vs + tau * (vs1 - vs), landing_vs)
            landing_vz = torch.where(lands, vz + tau * (vz1 - vz), landing_vz)
            active = active & ~lands
        s, z, vs, vz = s1, z1, vs1, vz1
        if step % 8 == 7 and not bool(active.any()):
            break
    return landing, clearance, landing_vs, landing_vz


def rebound_reaches(
    bounce_xy_m: torch.Tensor,
    heading: torch.Tensor,
    vs_m_s: torch.Tensor,
    vz_m_s: torch.Tensor,
    distribution: world_spec.IncomingBallDistribution = world_spec.INCOMING,
) -> torch.Tensor:
    """world_spec.rebound_reaches for many balls: after a nominal table bounce at bounce_xy [2, n] with
    contact velocity (vs along the unit heading [2, n], vz), does the ball pass through the paddle's
    reachable region before falling back to table level?

    The tangential contact response keeps the heading, so the rebound stays in the same vertical plane.
    Positions are checked four times per integration step (Hermite interpolation), i.e. every 5 ms.
    """
    out_s = world_spec.TABLE_TANGENTIAL_FACTOR * vs_m_s
    out_z = -world_spec.TABLE_RESTITUTION * vz_m_s
    centre = torch.tensor(distribution.reach_centre_m, dtype=vs_m_s.dtype, device=vs_m_s.device)
    # Offsets from the reach centre at the bounce (the ball centre sits at table + radius).
    dx0 = bounce_xy_m[0] - centre[0]
    dy0 = bounce_xy_m[1] - centre[1]
    z_contact = world_spec.TABLE_CONTACT_HEIGHT_M
    dt = 0.02
    s = torch.zeros_like(vs_m_s)
    z = torch.full_like(vs_m_s, z_contact)
    vs, vz = out_s, out_z
    reached = torch.zeros_like(s, dtype=torch.bool)
    active = torch.ones_like(reached)

    for step in range(int(world_spec.REBOUND_HORIZON_S / dt)):
        s1, z1, vs1, vz1 = _rk4_flight_step(s, z, vs, vz, dt, world_spec.DRAG_K_PER_M, world_spec.GRAVITY_M_S2)
        for tau in (0.25, 0.5, 0.75, 1.0):
            zi = _hermite(z, z1, vz, vz1, tau, dt)
            si = _hermite(s, s1, vs, vs1, tau, dt)
            active = active & (zi >= z_contact)  # fell back to table level: out of play or a 2nd bounce
            dx = dx0 + heading[0] * si
            dy = dy0 + heading[1] * si
            dz = zi - centre[2]
            inside = (zi >= distribution.min_hit_height_m) & (
                dx * dx + dy * dy + dz * dz <= distribution.reach_radius_m**2
            )
            reached = reached | (active & inside)
            active = active & ~inside
        s, z, vs, vz = s1, z1, vs1, vz1
        if step % 4 == 3 and not bool(active.any()):
            break
    return reached


class IncomingBallSampler:
    """Draws incoming balls (launch position, velocity, first-bounce point) in batches, as tensors.

    Reproducible: the same seed (and the same sequence of `sample` sizes) gives the same balls.
    """

    def __init__(
        self,
        speed_range_m_s: tuple[float, float] | None = None,
        seed: int = 0,
        device: str | torch.device = 'cpu',
        dtype: torch.dtype = torch.float32,
        distribution: world_spec.IncomingBallDistribution = world_spec.INCOMING,
        batch: int = 4096,
    ):
        self.distribution = distribution
        self.speed_range_m_s = tuple(speed_range_m_s or distribution.speed_m_s)
        if not self.speed_range_m_s[0] <= self.speed_range_m_s[1]:
            raise ValueError(f'speed range must be (low, high), got {self.speed_range_m_s}')
        self.device = torch.device(device)
        self.dtype = dtype
        self.batch = int(batch)
        self.solve_dtype = torch.float64  # the search needs the precision; float32 costs about as much
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(int(seed))
        empty = torch.empty(3, 0, dtype=dtype, device=self.device)
        self._bank = (empty, empty, empty[:2])

    def _uniform(self, n: int, bounds: tuple[float, float]) -> torch.Tensor:
        u = torch.rand(n, generator=self.generator, device=self.device, dtype=self.solve_dtype)
        return bounds[0] + (bounds[1] - bounds[0]) * u

    def _candidates(self, n: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """n draws; returns (launch [3, n], velocity [3, n], bounce [2, n], accepted [n])."""
        d = self.distribution
        start = torch.stack(
            (self._uniform(n, d.launch_x_m), self._uniform(n, d.launch_y_m), self._uniform(n, d.launch_z_m))
        )
        bounce = torch.stack((self._uniform(n, d.bounce_x_m), self._uniform(n, d.bounce_y_m)))
        speed = self._uniform(n, self.speed_range_m_s)
        offset = bounce - start[:2]
        distance = torch.linalg.vector_norm(offset, dim=0)
        heading = offset / distance
        height = start[2] - world_spec.TABLE_CONTACT_HEIGHT_M
        # The net plane x = 0 along the heading (launches are on the far side, bounces on the near one).
        net_distance = -start[0] / heading[0]

        def landing_error(elevation):
            landing, clearance, vs, vz = planar_flight(height, speed, elevation, net_distance)
            return landing - distance, clearance, vs, vz

        low = torch.full_like(speed, MIN_ELEVATION_RAD)
        high = torch.full_like(speed, MAX_ELEVATION_RAD)
        # Both ends of the bracket in one batch of flights.
        ends, _, _, _ = planar_flight(height.repeat(2), speed.repeat(2), torch.cat((low, high)), net_distance.repeat(2))
        f_low, f_high = (ends - distance.repeat(2)).chunk(2)
        reachable = (f_low <= 0.0) & (f_high >= 0.0) & torch.isfinite(f_high)
        elevation = self._solve_elevation(
            reachable,
            low,
            high,
            f_low,
            f_high,
            lambda idx, el: planar_flight(height[idx], speed[idx], el, net_distance[idx])[0] - distance[idx],
        )
        error, clearance, vs, vz = landing_error(elevation)
        velocity = torch.cat((speed * torch.cos(elevation) * heading, (speed * torch.sin(elevation))[None]))
        accepted = reachable & (clearance >= d.net_clearance_m) & (error.abs() < 1e-3)
        accepted = accepted & rebound_reaches(bounce, heading, vs, vz, d)
        return start, velocity, bounce, accepted

    @staticmethod
    def _solve_elevation(reachable, low, high, f_low, f_high, error_of) -> torch.Tensor:
        """Illinois iterations on the candidates whose bracket holds a root; converged ones drop out.

        error_of(indices, elevations) gives the landing errors of those candidates at those elevations.
        """
        elevation = 0.5 * (low + high)
        todo = torch.nonzero(reachable).squeeze(1)
        lo, hi, f_lo, f_hi = low[todo], high[todo], f_low[todo], f_high[todo]
        side = torch.zeros_like(lo)  # which end was replaced last: -1 low, +1 high
        for _ in range(ILLINOIS_ITERATIONS):
            if todo.numel() == 0:
                break
            mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            f_mid = error_of(todo, mid)
            elevation[todo] = mid
            below = f_mid < 0.0
            # Halve the stale end's value when the same end survives twice (keeps convergence superlinear).
            f_hi = torch.where(below & (side < 0), 0.5 * f_hi, f_hi)
            f_lo = torch.where(~below & (side > 0), 0.5 * f_lo, f_lo)
            lo, f_lo = torch.where(below, mid, lo), torch.where(below, f_mid, f_lo)
            hi, f_hi = torch.where(below, hi, mid), torch.where(below, f_hi, f_mid)
            side = torch.where(below, -torch.ones_like(side), torch.ones_like(side))
            keep = f_mid.abs() > 1e-6  # a micrometre from the bounce point is converged
            todo, lo, hi, f_lo, f_hi, side = todo[keep], lo[keep], hi[keep], f_lo[keep], f_hi[keep], side[keep]
        return elevation

    def _refill(self, needed: int) -> None:
        pos, vel, bounce = self._bank
        while pos.shape[1] < needed:
            start, velocity, point, accepted = self._candidates(self.batch)
            if not bool(accepted.any()):
                raise RuntimeError(f'no incoming ball found for speeds {self.speed_range_m_s} m/s')
            pos = torch.cat((pos, start[:, accepted].to(self.dtype)), dim=1)
            vel = torch.cat((vel, velocity[:, accepted].to(self.dtype)), dim=1)
            bounce = torch.cat((bounce, point[:, accepted].to(self.dtype)), dim=1)
        self._bank = (pos, vel, bounce)

    def sample(self, n: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The next n balls: launch position [3, n] m, launch velocity [3, n] m/s, bounce point [2, n] m."""
        self._refill(n)
        pos, vel, bounce = self._bank
        self._bank = (pos[:, n:], vel[:, n:], bounce[:, n:])
        return pos[:, :n], vel[:, :n], bounce[:, :n]
