"""Which optional effects a world's kernels are compiled with: what a scene does not use costs
nothing (house rule 8).

An effect is either asked for by name in the scene's ``effects`` list (a user's choice:
``friction``, ``restitution``, ``sleeping``), follows from the bodies with no choice to make
(``gyroscopic``: some dynamic body's inertia is anisotropic, so w x (I w) is not zero;
``damping``: some dynamic body has linear or angular damping; ``light_bodies``: some dynamic body
is ``Settings.ratio_mass`` times lighter than another, so it may rest under it and take the Jacobi
family's extra sweeps, solvers/light_bodies.py), or from a world setting
(``speculative``: Settings.speculative_contacts). An asked-for contact effect is still
compiled away when no body can use it: friction when every friction coefficient is 0,
restitution when every restitution is 0, rolling and torsional friction (with the friction
effect) when every body's rolling and torsional coefficients are 0. The flags are
compile-time switches of the step's kernels, so each combination compiles its own kernels
on first use (Taichi caches them); the world re-derives them after every edit of its bodies.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


LIGHT_MARGIN = 0.999
"""[1] How near a world's mass spread (build.HostWorld.mass_spread) may come to
``Settings.ratio_mass`` and still leave the light bodies' sweeps out: the kernels' own float32 test
(light_bodies.mark_light) picks the light bodies, and it must never find one the switch left out."""


@dataclass(frozen=True)
class CompiledEffects:
    friction: bool  # friction rows are built and solved
    restitution: bool  # the bounce pass runs after the substeps
    gyroscopic: bool  # the rotation update solves the implicit gyroscopic term (integrate.rotate_free)
    sleeping: bool  # resting islands sleep and the loops visit the awake bodies only (sleep.py)
    damping: bool = False  # the position update damps velocities (integrate.advance_pose)
    rolling_friction: bool = False  # torsional and rolling rows are solved (rolling.solve_rolling)
    speculative: bool = True  # AABBs and pair margins grow by the distance a shape can move (broadphase.py)
    light_bodies: bool = True  # the Jacobi family's extra sweeps over light bodies' blocks (light_bodies.py;
    # compiled out under CUDA's loop shapes only: on the CPU their empty loops cost nothing, step.py)

    def as_dict(self) -> dict[str, bool]:
        return asdict(self)


def compile_effects(asked: tuple, host, settings, anisotropic_reserved: bool = False,
                    spread_reserved: float = 1.0) -> CompiledEffects:
    """The switches for a world that asks for ``asked``, holds ``host`` (build.HostWorld) and
    runs with ``settings`` (settings.Settings). ``anisotropic_reserved``: bodies with an
    anisotropic inertia may be added later (World's ``reserve_kinds``), so the gyroscopic step is
    compiled in from the start rather than when the first such body arrives; ``spread_reserved``:
    the mass spread the bodies that may be added could bring (a scene's drops; fracture pieces and
    reserved bodies, of any mass: inf), so the light bodies' sweeps are compiled in from the start."""
    return CompiledEffects(
        friction="friction" in asked and host.has_friction,
        restitution="restitution" in asked and host.has_restitution,
        gyroscopic=host.has_gyroscopic or anisotropic_reserved,
        sleeping="sleeping" in asked,
        damping=host.has_damping,
        rolling_friction="friction" in asked and host.has_rolling_friction,
        speculative=settings.speculative_contacts,
        light_bodies=settings.ratio_sweeps > 0
        and max(host.mass_spread, spread_reserved) >= settings.ratio_mass * LIGHT_MARGIN,
    )
