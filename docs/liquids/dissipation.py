"""The method's own viscosity at 5 mm (no XSPH) under solver settings that dissipate less.

Each line: the settings changed from PBFConfig's defaults, and the Kelvin-Voigt fit of the
shear wave (pour_gym.fluid.validation.shear_wave): viscosity (m^2/s) and elastic wave
speed (m/s). About a minute a line, one thread (docs/liquids.md, "Not done yet").

    python docs/liquids/dissipation.py
"""

from pour_gym.fluid.pbf import PBFConfig
from pour_gym.fluid.validation import shear_wave

CASES = (
    {},
    {"iterations": 8},
    {"iterations": 16},
    {"iterations": 8, "over_relaxation": 1.0},
    {"substep": 1 / 480},
)
for changed in CASES:
    wave = shear_wave(config=PBFConfig(xsph=0.0, **changed), num_threads=1)
    print(f"{changed or 'defaults'}: {wave.viscosity:.2e} m^2/s, {wave.wave_speed:.3f} m/s")
