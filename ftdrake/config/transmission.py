"""Typed configuration of the compliant joint transmissions (motor, gearbox spring, link).

Read as ``scenario.transmission`` (see :class:`~ftdrake.config.ScenarioConfig`), with the same
YAML loader as the rest of the tree. Off by default: the rigid-joint scenario is unchanged.

Every per-joint list has one entry per arm joint, proximal first. Units: link (output) side,
SI: N·m/rad, N·m·s/rad, kg·m² (the motor's own rotor inertia is on the motor shaft).

Where the default numbers come from (the simulated arm is a 7-axis arm of about 10 kg payload;
its gearboxes are those of that size class):

* Gear ratio N: industrial arm joints use harmonic drives of ratio 50–160 or RV
  (cycloid) reducers of ratio 57–161 (Harmonic Drive CSF/CSG catalogue, "Rating table":
  ratios 30, 50, 80, 100, 120, 160; Nabtesco RV-E catalogue: ratios 57–161). Defaults:
  120 at the shoulder, 100 at elbow and wrist, 80 at the last two axes.
* Torsional stiffness k: Nabtesco RV-E catalogue lists torsional rigidity in N·m/arcmin
  (RV-20E about 49, RV-40E about 108 → 1.7·10⁵ and 3.7·10⁵ N·m/rad); Harmonic Drive
  CSF/CSG catalogues list K1–K3 from about 10³ N·m/rad (size 11–14) to 10⁵ N·m/rad (size
  32–40), "Torsional stiffness". Defaults: 1.7·10⁵ (RV-20E class) at S and L, 5·10⁴
  (HD size 32 class) at E and U, 1.3·10⁴ (HD size 20 class) at R and B, 5·10³ (HD size
  14–17 class) at T. These are catalogue orders of magnitude, not a particular robot's.
* Rotor inertia J_m: AC servo motors of 100–750 W have rotor inertias of about 0.1–1.6·10⁻⁴
  kg·m² (Yaskawa Σ-7 SGM7J catalogue, "rotor moment of inertia"). The reflected inertia
  J_m·N² (0.1–2.3 kg·m² here) is often larger than the link's own inertia about the joint,
  as in the flexible-joint literature (Spong, "Modeling and control of elastic joint
  robots", 1987; Albu-Schäffer et al., "The DLR lightweight robot", 2007).
* Damping: gearbox structural damping is small; identified flexible-joint models report
  modal damping ratios of a few per cent (e.g. Ruderman & Bertram, "Modeling and
  observation of hysteresis lost motion in elastic robot joints", 2012, for harmonic
  drives). Default ζ = 0.05 of the motor-against-held-link mode, d = 2ζ√(k·J_m N²).
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import math

from ..errors import ConfigError


@dc.dataclass
class TransmissionConfig:
    """Per-joint motor + gearbox spring/damper + link (two-mass model), off by default.

    With ``enabled``, each arm joint is driven through a spring ``k`` and damper ``d``
    from a motor of reflected inertia ``rotor_inertia · gear_ratio²``; the controller reads
    the motor angle divided by the gear ratio (the encoder is on the motor shaft) and
    commands the motor torque (expressed at the output, N·m). With ``chain_reads_motors``
    the F/T loop and the log read the motor side too (see the field's comment).
    """

    enabled: bool = False
    gear_ratio: list[float] = dc.field(
        default_factory=lambda: [120.0, 120.0, 100.0, 100.0, 100.0, 80.0, 80.0])
    stiffness: list[float] = dc.field(  # N·m/rad at the output
        default_factory=lambda: [1.7e5, 1.7e5, 5.0e4, 5.0e4, 1.3e4, 1.3e4, 5.0e3])
    rotor_inertia: list[float] = dc.field(  # kg·m² on the motor shaft
        default_factory=lambda: [1.6e-4, 1.6e-4, 0.9e-4, 0.9e-4, 0.3e-4, 0.3e-4, 0.15e-4])
    damping_ratio: float = 0.05  # of the motor-against-held-link mode
    # The gearbox's kinematic (transmission) error, rad at the output, per joint (empty: none):
    # the link end of the spring stands at φ + e·sin(c·N·φ), c cycles per motor revolution.
    # A harmonic drive's is 1–1.5 arcmin (2.9–4.4·10⁻⁴ rad) peak to peak, twice per
    # wave-generator turn (Harmonic Drive CSF/CSG catalogue, "Transmission accuracy"; Tuttle
    # & Seering, "A nonlinear model of a harmonic drive gear transmission", 1996): a ripple
    # whose frequency grows with speed, the usual source of a moving arm's vibration.
    transmission_error: list[float] = dc.field(default_factory=list)
    transmission_error_cycles: float = 2.0
    # Real controllers include the reflected rotor inertia in their dynamic model.
    controller_knows_rotor_inertia: bool = True
    # The F/T loop's joint state (the runtime chain's input and the log's q, q̇, q̈ columns):
    # False, the links' (the plant's state); True, the motor-side encoders' (φ, φ̇ and the
    # motors' acceleration), as on an arm whose encoders sit on the motor shafts, so that
    # the wrist's vibration on the gearbox springs is in the wrench but not in the joints.
    chain_reads_motors: bool = False

    def validate(self, where: str = "scenario.transmission") -> "TransmissionConfig":
        n = len(self.gear_ratio)
        for name in ("stiffness", "rotor_inertia"):
            values = getattr(self, name)
            if len(values) != n:
                raise ConfigError(f"{where}.{name}: must have one entry per joint like "
                                  f"gear_ratio ({n}), got {len(values)}")
        self._validate_transmission_error(where, n)
        for name in ("gear_ratio", "stiffness", "rotor_inertia"):
            for i, v in enumerate(getattr(self, name)):
                if not (math.isfinite(v) and v > 0):
                    raise ConfigError(f"{where}.{name}[{i}]: must be finite and > 0, got {v}")
        if self.chain_reads_motors and not self.enabled:
            raise ConfigError(f"{where}.chain_reads_motors: needs {where}.enabled: true (the "
                              "motor-side encoders exist only with the compliant joints)")
        if not (math.isfinite(self.damping_ratio) and self.damping_ratio >= 0):
            raise ConfigError(f"{where}.damping_ratio: must be finite and >= 0, got "
                              f"{self.damping_ratio}")
        return self

    def _validate_transmission_error(self, where: str, n: int) -> None:
        if self.transmission_error and len(self.transmission_error) != n:
            raise ConfigError(f"{where}.transmission_error: must be empty or have one entry per "
                              f"joint like gear_ratio ({n}), got {len(self.transmission_error)}")
        for i, v in enumerate(self.transmission_error):
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{where}.transmission_error[{i}]: must be finite and >= 0 "
                                  f"(rad), got {v}")
        if not (math.isfinite(self.transmission_error_cycles)
                and self.transmission_error_cycles > 0):
            raise ConfigError(f"{where}.transmission_error_cycles: must be finite and > 0, got "
                              f"{self.transmission_error_cycles}")

    def has_transmission_error(self) -> bool:
        """Whether any joint has a gearbox kinematic error (``transmission_error``)."""
        return any(v > 0 for v in self.transmission_error)

    def reflected_inertia(self) -> list[float]:
        """J_m · N² per joint (kg·m²): the motor's inertia seen at the output."""
        return [j * r * r for j, r in zip(self.rotor_inertia, self.gear_ratio, strict=True)]

    def damping(self) -> list[float]:
        """d = 2ζ√(k·J_m N²) per joint (N·m·s/rad)."""
        return [2.0 * self.damping_ratio * math.sqrt(k * J)
                for k, J in zip(self.stiffness, self.reflected_inertia(), strict=True)]
