"""A small family of scenes: the seed with five damper coefficients, through the reduced engine
(``loopcheck sweep`` does this at scale, on every core, with plots).

    python examples/damper_sweep.py
"""

import tomllib

import loopcheck

data = tomllib.loads(loopcheck.catalogue()["seed_fourbar"].read_text())  # the scene file's keys, as a dict
for coefficient in (40.0, 47.5, 55.0, 62.5, 70.0):  # N·s/m
    data["dampers"][0]["coefficient"] = coefficient
    scene = loopcheck.scene_from_dict(data)
    result = loopcheck.simulate(scene, loopcheck.ReducedSettings(rtol=1e-10))
    print(f"damper {coefficient:5.1f} N·s/m: peak {result.peak.omega:.6f} rad/s at {result.peak.time:.4f} s")
