"""Model build and raw stepping speed of the generated models (prints figures)."""

import time

import mujoco

from toddlerbot.robot.builder import build_model, build_xml
from toddlerbot.robot.spec import load_spec


def main() -> None:
    spec = load_spec()
    start = time.perf_counter()
    for _ in range(5):
        build_xml(spec, "floating", scene=True)
    print(f"build MJCF (floating + scene): {(time.perf_counter() - start) / 5 * 1e3:.1f} ms")
    for base in ("floating", "fixed"):
        model = build_model(spec, base, scene=True)
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        steps = 20_000
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        rate = steps / (time.perf_counter() - start)
        print(f"raw mj_step, {base}: {rate:,.0f} steps/s (real-time factor {rate * model.opt.timestep:.1f})")


if __name__ == "__main__":
    main()
