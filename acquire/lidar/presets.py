"""Scanner presets from the makers' published specifications.

Each preset is a :class:`ScannerPreset`: pulse rate, wavelength, beam divergence, scan
pattern, field of view and scan rate, range precision, maximum range, pulse width and
maximum returns. The sources are listed per preset (``sources``) and in docs/lidar.md;
where a datasheet gives no figure (pulse width, a detection threshold) the value is an
assumption said so in ``notes``, usually the one HELIOS++ uses for the same scanner.

>>> get_preset("riegl-lms-q560").pattern
'polygon'
>>> sorted(PRESETS)[:2]
['leica-als50-ii', 'livox-avia']
"""

from __future__ import annotations

from dataclasses import dataclass, field

from core.validate import InputError

__all__ = ["ScannerPreset", "PRESETS", "get_preset", "PATTERNS", "PLATFORM_KINDS"]

#: Scan patterns (see :mod:`acquire.lidar.patterns`).
PATTERNS = ("oscillating", "polygon", "conic", "spinning", "rosette")
#: Platforms a preset is made for (see :mod:`acquire.lidar.platforms`).
PLATFORM_KINDS = ("airplane", "multicopter", "vehicle", "tripod")


@dataclass(frozen=True)
class ScannerPreset:
    """A scanner's published specification.

    Attributes
    ----------
    name : str
    model : str
        Maker and model.
    platform : {'airplane', 'multicopter', 'vehicle', 'tripod'}
        The platform it is usually flown, driven or set up on.
    pattern : {'oscillating', 'polygon', 'conic', 'spinning', 'rosette'}
    pulse_rates_hz : tuple of float
        Selectable pulse repetition rates (effective measurement rates), Hz.
    wavelength_nm : float
    divergence_mrad : float
        Full beam divergence at the 1/e^2 points, mrad (a circular cone; an elliptical
        beam is given its geometric mean).
    fov_deg : (float, float)
        Scan angles covered, degrees: across track from nadir (airborne), elevation
        (spinning, terrestrial), or the cone's half-angle twice (conic, rosette).
    scan_rate_hz : (float, float)
        Lines, rotations or mirror periods per second: the selectable range.
    precision_m : float
        Range precision (one sigma) at ``precision_range_m`` on a target of reflectance
        ``reference_reflectance`` at normal incidence.
    precision_range_m : float
    max_range_m : float
        Range where an echo of a ``reference_reflectance`` target at normal incidence is
        just detected (sets the detection threshold).
    reference_reflectance : float
    min_range_m : float
    pulse_width_ns : float
        Emitted pulse, full width at half maximum.
    max_returns : int
    detection : {'waveform', 'discrete'}
        The receiver (:mod:`acquire.lidar.waveform`): a digitised waveform decomposed
        into echoes (of two close echoes the stronger is kept), or an analogue detector
        triggering on each echo in time with a dead time (the earlier is kept).
    min_separation_m : float
        Echoes closer in range than this are one; 0: the pulse's width in range
        (``c * pulse_width / 2``), what a waveform's decomposition resolves.
    channels_deg : tuple of float
        Elevation of each beam of a multi-beam (spinning) scanner, degrees.
    prism_hz : (float, float)
        Rotation rates of a rosette scanner's two Risley prisms, Hz.
    head_rate_deg_s : float
        Pan rate of a terrestrial scanner's head, degrees per second.
    sources : tuple of str
    notes : str
    """

    name: str
    model: str
    platform: str
    pattern: str
    pulse_rates_hz: tuple
    wavelength_nm: float
    divergence_mrad: float
    fov_deg: tuple
    scan_rate_hz: tuple
    precision_m: float
    precision_range_m: float
    max_range_m: float
    reference_reflectance: float
    min_range_m: float
    pulse_width_ns: float
    max_returns: int
    detection: str = "waveform"
    min_separation_m: float = 0.0
    channels_deg: tuple = ()
    prism_hz: tuple = ()
    head_rate_deg_s: float = 0.0
    sources: tuple = field(default_factory=tuple)
    notes: str = ""

    @property
    def pulse_rate_hz(self) -> float:
        """The highest selectable pulse rate (the default)."""
        return float(max(self.pulse_rates_hz))


PRESETS: dict[str, ScannerPreset] = {p.name: p for p in (
    ScannerPreset(
        name="riegl-lms-q560", model="RIEGL LMS-Q560", platform="airplane", pattern="polygon",
        pulse_rates_hz=(50e3, 100e3, 180e3, 200e3, 240e3), wavelength_nm=1550.0,
        divergence_mrad=0.5, fov_deg=(-22.5, 22.5), scan_rate_hz=(10.0, 160.0),
        precision_m=0.02, precision_range_m=250.0, max_range_m=800.0,
        reference_reflectance=0.2, min_range_m=30.0, pulse_width_ns=4.0, max_returns=7,
        sources=("RIEGL LMS-Q560 datasheet (2010): 240 kHz, 0.5 mrad, +/-22.5 deg, "
                 "10-160 lines/s, accuracy 20 mm, near-infrared",
                 "HELIOS++ scanners_als.xml riegl_lms-q560 (pulse length 4 ns)"),
        notes="full-waveform scanner (returns unlimited): capped at 7 here; the range for "
              "20 % reflectance at 240 kHz (800 m) and the precision's reference range "
              "(250 m) are assumptions, not datasheet figures"),
    ScannerPreset(
        name="riegl-vq-880g", model="RIEGL VQ-880-G (green channel)", platform="airplane",
        pattern="conic", pulse_rates_hz=(200e3, 400e3, 550e3), wavelength_nm=532.0,
        divergence_mrad=0.7, fov_deg=(-20.0, 20.0), scan_rate_hz=(30.0, 80.0),
        precision_m=0.025, precision_range_m=250.0, max_range_m=1000.0,
        reference_reflectance=0.2, min_range_m=10.0, pulse_width_ns=2.0, max_returns=9,
        sources=("RIEGL VQ-880-G datasheet: circular scan, 40 deg FOV (20 deg off nadir), "
                 "up to 550 kHz, green 532 nm, divergence 0.7-2.0 mrad, accuracy 25 mm",
                 "HELIOS++ scanners_als.xml riegl_vq-880g (pulse length 2 ns, 9 returns)"),
        notes="green channel; reflectance at 532 nm is the material's green albedo"),
    ScannerPreset(
        name="riegl-vz-400", model="RIEGL VZ-400", platform="tripod", pattern="polygon",
        pulse_rates_hz=(42e3, 122e3), wavelength_nm=1550.0, divergence_mrad=0.3,
        fov_deg=(-40.0, 60.0), scan_rate_hz=(3.0, 120.0), precision_m=0.003,
        precision_range_m=100.0, max_range_m=280.0, reference_reflectance=0.2,
        min_range_m=1.5, pulse_width_ns=5.0, max_returns=7, head_rate_deg_s=60.0,
        sources=("RIEGL VZ-400 datasheet (2014): effective rate 42 000 / 122 000 meas/s, "
                 "0.3 mrad, vertical +60/-40 deg, horizontal 360 deg, 3-120 lines/s, "
                 "precision 3 mm / accuracy 5 mm at 100 m, 280 m at 20 % (100 kHz PRR)",
                 "HELIOS++ scanners_tls.xml riegl_vz400 (pulse length 5 ns, head 60 deg/s)"),
        notes="online waveform processing (returns practically unlimited): capped at 7"),
    ScannerPreset(
        name="velodyne-vlp16", model="Velodyne VLP-16 (Puck)", platform="vehicle",
        pattern="spinning", pulse_rates_hz=(300e3,), wavelength_nm=903.0,
        divergence_mrad=2.1, fov_deg=(-15.0, 15.0), scan_rate_hz=(5.0, 20.0),
        precision_m=0.03, precision_range_m=50.0, max_range_m=100.0,
        reference_reflectance=0.2, min_range_m=0.5, pulse_width_ns=5.0, max_returns=2,
        channels_deg=tuple(float(a) for a in range(-15, 16, 2)),
        sources=("Velodyne VLP-16 user manual and datasheet (63-9229): 16 channels, "
                 "+/-15 deg in 2 deg steps, 5-20 Hz, ~300 000 points/s single return, "
                 "903 nm, range 100 m, accuracy +/-3 cm, dual returns",
                 "divergence 3.0 x 1.5 mrad (manual), geometric mean 2.1 mrad"),
        notes="dual return mode reports two echoes; here the first two in time"),
    ScannerPreset(
        name="livox-avia", model="Livox Avia", platform="multicopter", pattern="rosette",
        pulse_rates_hz=(240e3,), wavelength_nm=905.0, divergence_mrad=1.6,
        fov_deg=(-35.2, 35.2), scan_rate_hz=(10.0, 10.0), precision_m=0.02,
        precision_range_m=20.0, max_range_m=190.0, reference_reflectance=0.1,
        min_range_m=1.0, pulse_width_ns=4.0, max_returns=3, prism_hz=(-77.733, 121.567),
        sources=("Livox Avia datasheet: 905 nm, 70.4 deg circular non-repetitive FOV, "
                 "240 000 points/s (first return), 3 returns, range 190 m at 10 %, "
                 "precision 2 cm at 20 m, divergence 0.28 x 0.03 deg",
                 "HELIOS++ scanners_als.xml livox_mid-70: Risley prism rates -77.7 / "
                 "121.6 Hz (the Avia's rosette)"),
        notes="elliptical 4.9 x 0.52 mrad beam given its geometric mean 1.6 mrad"),
    ScannerPreset(
        name="leica-als50-ii", model="Leica ALS50-II", platform="airplane",
        pattern="oscillating", pulse_rates_hz=(20e3, 60e3, 150e3), wavelength_nm=1064.0,
        divergence_mrad=0.22, fov_deg=(-37.5, 37.5), scan_rate_hz=(1.0, 90.0),
        precision_m=0.05, precision_range_m=1000.0, max_range_m=4000.0,
        reference_reflectance=0.2, min_range_m=200.0, pulse_width_ns=10.0, max_returns=4,
        detection="discrete", min_separation_m=2.7,
        sources=("NERC-ARF wiki, Sensors/LeicaLIDAR (the ALS50-II they flew from 2009): "
                 "1064 nm, 0.22 mrad, 75 deg FOV; two banks of 4 timing cards, so up to 4 "
                 "returns per pulse; a minimum time between returns, so two returns must "
                 "be at least 2.7 m apart",
                 "HELIOS++ scanners_als.xml leica_als50-ii: 20/60/150 kHz, 10 ns pulse, "
                 "oscillating mirror, +/-37.5 deg, 0-90 Hz, accuracy 0.05 m, 4 returns "
                 "('vertical discrimination distance approx. 3.5 m')"),
        notes="discrete-return receiver (first, second, third, fourth echo in time); the "
              "minimum separation is the operator's 2.7 m (HELIOS++ says about 3.5 m); "
              "the maximum range (4000 m at 20 %) and the precision's reference range "
              "(1000 m) are assumptions, not datasheet figures"),
)}


def get_preset(name: str) -> ScannerPreset:
    """The preset called ``name``; InputError listing every known one otherwise."""
    try:
        return PRESETS[str(name)]
    except KeyError:
        raise InputError(f"unknown preset {name!r}; expected one of "
                         f"{', '.join(sorted(PRESETS))}", field="preset") from None
