"""The editor page: viser controls wired to the edited keyframes, the 3D robot, playback and saving.

Layout (side panel, top to bottom): Motion (status line, name, interpolation, save path, Save), Keyframes (table,
selected keyframe, duration, add/delete/move, mirror, where the torso is: upright, on the back or front, or any
roll and pitch), Simulate (play in MuJoCo, result), then one folder of
joint sliders per limb, in degrees, over each joint's range from the spec. Every control acts on the selected
keyframe; the 3D view shows it standing on the floor with its centre of mass and support polygon.

Controls call back on viser's thread pool, so one (re-entrant) lock guards the document; values set from here also
fire the callbacks, synchronously on the same thread and so inside the lock, where `_quiet` turns them into no-ops
(a user's change from another thread waits for the lock and then applies).
"""

from __future__ import annotations

import contextlib
import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import viser

import toddlerbot
from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write_text
from toddlerbot.motion_editor.balance import PoseModel
from toddlerbot.motion_editor.keyframes import MAX_DURATION_S, MIN_DURATION_S, Keyframes
from toddlerbot.motion_editor.mirror import MirrorMap
from toddlerbot.motion_editor.playback import Playback, simulate
from toddlerbot.motion_editor.scene import RobotScene
from toddlerbot.motion_editor.topview import top_view
from toddlerbot.policies.motions import INTERPOLATIONS, BasePose, MotionError, load_motion
from toddlerbot.robot.description import RobotDescription

PACKAGE_DIR = Path(toddlerbot.__file__).resolve().parent
GROUP_ORDER = ("neck", "waist", "arm", "leg", "gripper")
FRAME_PERIOD_S = 0.04
"""Playback redraw period, s (25 frames per second of simulated time)."""
TOP_VIEW_EVERY = 5
"""Redraw the balance top view every this many playback frames (5 per second)."""
EDIT_ACTIONS = ("Add", "Delete", "Earlier", "Later")
MIRROR_ACTIONS = ("Left → right", "Right → left", "Swap")
TORSO_ACTIONS = {"Upright": None, "On back": BasePose(pitch=-np.pi / 2), "On front": BasePose(pitch=np.pi / 2)}
"""The torso's base pose each Torso button gives the selected keyframe (None: standing upright)."""


def limb_groups(description: RobotDescription) -> dict[str, list[str]]:
    """Output joints by limb: the spec's motor groups split into left and right ("Left arm", "Neck", ...)."""
    out: dict[str, list[str]] = {}
    groups = description.groups
    for group in (*GROUP_ORDER, *sorted(set(groups) - set(GROUP_ORDER))):
        for i in groups.get(group, ()):
            joint = description.joint_names[i]
            side = next((s for s in ("left", "right") if joint.startswith(f"{s}_")), None)
            label = f"{side.capitalize()} {group}" if side else group.capitalize()
            out.setdefault(label, []).append(joint)
    return out


def check_save_path(text: str) -> Path:
    """The file to save to, or `MotionError`: a name is given, ends in .yaml/.yml, is not a folder, and lies
    outside the installed package (a built-in motion is saved as a copy, never over the packaged file)."""
    if not text.strip():
        raise MotionError("name a file to save to (a built-in motion is saved as a copy, e.g. my_wave.yaml)")
    path = Path(text.strip()).expanduser()
    if path.suffix not in (".yaml", ".yml"):
        raise MotionError(f"{path}: expected a file name ending in .yaml")
    if path.is_dir():
        raise MotionError(f"{path}: is a folder, expected a motion file name")
    if path.resolve().is_relative_to(PACKAGE_DIR):
        raise MotionError(f"{path}: inside the installed toddlerbot package; save the motion as a copy elsewhere")
    return path


class MotionEditor:
    def __init__(self, server: viser.ViserServer, description: RobotDescription, keyframes: Keyframes,
                 save_path: Path | None) -> None:
        self.server = server
        self.description = description
        self.doc = keyframes
        self.current = 0
        self.mirror = MirrorMap.of(description)
        self.poses = PoseModel(description)
        self.playback: Playback | None = None
        self._lock = threading.RLock()
        self._quiet = False
        self._playing = threading.Event()
        server.scene.set_up_direction("+z")
        server.initial_camera.position = (0.6, -0.37, 0.4)
        server.initial_camera.look_at = (0.0, 0.0, 0.2)
        self.scene = RobotScene(server, self.poses.model)
        self._build_gui(save_path)
        self._refresh()

    # -- page ------------------------------------------------------------------------------------------------
    def _build_gui(self, save_path: Path | None) -> None:
        gui = self.server.gui
        gui.configure_theme(control_width="large", show_logo=False, show_share_button=False)
        gui.main_panel.dock_right()
        with gui.add_folder("Motion"):
            self.status = gui.add_markdown("Ready.")
            self.name = gui.add_text("Name", self.doc.name)
            self.interpolation = gui.add_dropdown("Interpolation", INTERPOLATIONS, initial_value=self.doc.interpolation)
            self.save_path = gui.add_text("Save to", "" if save_path is None else str(save_path),
                                          hint="Motion YAML to write; relative to where the editor was started")
            self.save_button = gui.add_button("Save", icon=viser.Icon.DEVICE_FLOPPY)
        with gui.add_folder("Keyframes"):
            self.table = gui.add_markdown("")
            self.balance_view = gui.add_image(np.full((8, 8, 3), 255, np.uint8), label="Balance (top view)",
                                              format="png")
            self.selected = gui.add_dropdown("Keyframe", self._keyframe_labels())
            self.duration = gui.add_number("Duration (s)", 1.0, min=MIN_DURATION_S, max=MAX_DURATION_S, step=0.05,
                                           hint="Time to reach this keyframe from the one before")
            self.edit = gui.add_button_group("Edit", EDIT_ACTIONS)
            self.mirror_buttons = gui.add_button_group("Mirror", MIRROR_ACTIONS)
            self.mirror_edits = gui.add_checkbox("Mirror slider edits", False,
                                                 hint="Moving a left or right joint moves its partner too")
            self.torso = gui.add_button_group("Torso", tuple(TORSO_ACTIONS))
            self.torso_pitch = gui.add_slider("Torso pitch", min=-180.0, max=180.0, step=1.0, initial_value=0.0,
                                              hint="deg, > 0 leans forward: -90 lies on the back, 90 on the front")
            self.torso_roll = gui.add_slider("Torso roll", min=-180.0, max=180.0, step=1.0, initial_value=0.0,
                                             hint="deg, > 0 tips the torso onto its right side")
        with gui.add_folder("Simulate"):
            self.play_button = gui.add_button("Play in simulator", icon=viser.Icon.PLAYER_PLAY)
            self.see_through = gui.add_checkbox("See-through robot", False, hint="Show the CoM inside the body")
            self.result = gui.add_markdown("Play runs the motion in MuJoCo with the actuator model "
                                           "(as `sim run --policy replay`).")
        self.sliders: dict[str, viser.GuiSliderHandle] = {}
        rng = np.rad2deg(self.description.joint_range)
        for limb, joints in limb_groups(self.description).items():
            with gui.add_folder(limb, expand_by_default=limb == "Right arm"):
                for joint in joints:
                    k = self.description.joint_names.index(joint)
                    lo, hi = float(np.round(rng[k, 0], 1)), float(np.round(rng[k, 1], 1))
                    slider = gui.add_slider(joint, min=lo, max=hi, step=0.5, initial_value=float(np.clip(0.0, lo, hi)),
                                            hint=f"{joint}: {lo:g} to {hi:g} deg")
                    slider.on_update(self._joint_callback(joint))
                    self.sliders[joint] = slider
        self.name.on_update(lambda _: self._set_name())
        self.interpolation.on_update(lambda _: self._set_interpolation())
        self.selected.on_update(lambda _: self._select())
        self.duration.on_update(lambda _: self._set_duration())
        self.edit.on_click(lambda event: self._edit(event.target.value))
        self.mirror_buttons.on_click(lambda event: self._mirror(event.target.value))
        self.torso.on_click(lambda event: self.set_base(TORSO_ACTIONS[event.target.value]))
        self.torso_pitch.on_update(lambda _: self._set_tilt())
        self.torso_roll.on_update(lambda _: self._set_tilt())
        self.play_button.on_click(lambda _: self.play())
        self.see_through.on_update(lambda _: self.scene.see_through(self.see_through.value))
        self.save_button.on_click(lambda _: self.save(self.save_path.value))

    def _keyframe_labels(self) -> tuple[str, ...]:
        return tuple(f"{i}: t = {t:.2f} s" for i, t in enumerate(self.doc.times))

    # -- callbacks -------------------------------------------------------------------------------------------
    def _joint_callback(self, joint: str):
        def on_update(_event) -> None:
            with self._lock:
                if self._quiet:
                    return
                self.doc.set_joint(self.current, joint, np.deg2rad(self.sliders[joint].value))
                if self.mirror_edits.value:
                    follow = self.mirror.follow(self.doc.poses[self.current], joint)
                    if follow is not None:
                        self.doc.set_joint(self.current, *follow)
                self._refresh(sliders=self.mirror_edits.value)
        return on_update

    def _set_name(self) -> None:
        with self._lock:
            if not self._quiet:
                self.doc.name = self.name.value.strip() or "motion"

    def _set_interpolation(self) -> None:
        with self._lock:
            if not self._quiet:
                self.doc.interpolation = self.interpolation.value

    def _select(self) -> None:
        with self._lock:
            if self._quiet:
                return
            self.current = self._keyframe_labels().index(self.selected.value)
            self._refresh()

    def _set_duration(self) -> None:
        with self._lock, self._reported():
            if self._quiet:
                return
            self.doc.set_duration(self.current, float(self.duration.value))
            self._refresh()

    def _edit(self, action: str) -> None:
        with self._lock, self._reported():
            if action == "Add":
                self.current = self.doc.insert_after(self.current)
            elif action == "Delete":
                self.current = self.doc.delete(self.current)
            else:
                self.current = self.doc.move(self.current, -1 if action == "Earlier" else 1)
            self._refresh()
            self._say(f"{action.lower()}: keyframe {self.current} selected, {len(self.doc)} keyframes, "
                      f"{self.doc.times[-1]:.2f} s")

    def _mirror(self, action: str) -> None:
        with self._lock:
            pose = self.doc.poses[self.current]
            if action == "Swap":
                pose = self.mirror.swapped(pose)
            else:
                pose = self.mirror.copied(pose, "left" if action.startswith("Left") else "right")
            self.doc.set_pose(self.current, pose)
            self._refresh()
            self._say(f"keyframe {self.current}: mirrored ({action})")

    def set_base(self, base: BasePose | None) -> None:
        """Where the torso is at the selected keyframe (None: standing upright); the first keyframe's is where Play
        starts."""
        with self._lock:
            self.doc.set_base(self.current, base)
            self._refresh()
            self._say(f"keyframe {self.current}: {_torso_words(base)}")

    def _set_tilt(self) -> None:
        with self._lock:
            if self._quiet:
                return
            roll, pitch = np.deg2rad(self.torso_roll.value), np.deg2rad(self.torso_pitch.value)
            z = (self.doc.bases[self.current] or BasePose()).z
            upright = roll == pitch == 0.0 and z is None
            self.doc.set_base(self.current, None if upright else BasePose(roll=roll, pitch=pitch, z=z))
            self._refresh(sliders=False)

    # -- actions ---------------------------------------------------------------------------------------------
    def play(self, wait: bool = False) -> Playback | None:
        """Simulate the motion and animate the result in real time (on a worker thread unless `wait`)."""
        if self._playing.is_set():
            return None
        motion = None
        with self._lock, self._reported():
            motion = self.doc.to_motion(f"motion {self.doc.name!r}")
        if motion is None:  # the status line says why
            return None
        self._playing.set()
        self.play_button.disabled = True
        self.result.content = f"Simulating {motion.duration:.2f} s ..."

        def run() -> Playback | None:
            try:
                playback = simulate(self.description, motion)
                self.playback = playback
                self.result.content = f"**{playback.describe()}**"
                self._animate(playback)
                return playback
            except ToddlerbotError as exc:
                self.result.content = f"**error:** {exc}"
                return None
            finally:
                self.play_button.disabled = False
                self._playing.clear()

        if wait:
            return run()
        threading.Thread(target=run, name="motion-play", daemon=True).start()
        return None

    def _animate(self, playback: Playback) -> None:
        model = self.poses.model
        data = mujoco.MjData(model)
        step = max(1, round(FRAME_PERIOD_S / float(np.median(np.diff(playback.times))))) if len(playback.times) > 1 \
            else 1
        start = time.perf_counter()
        frames = range(0, len(playback.times), step)
        for n, i in enumerate(frames):
            data.qpos[:] = playback.qpos[i]
            mujoco.mj_kinematics(model, data)
            self.scene.show(data, playback.balance[i])
            if n % TOP_VIEW_EVERY == 0 or n == len(frames) - 1:  # a picture per frame would flood a slow browser
                self.balance_view.image = top_view(playback.balance[i], self.poses.soles(data))
            time.sleep(max(0.0, start + playback.times[i] - playback.times[0] - time.perf_counter()))

    def save(self, path_text: str) -> Path | None:
        """Validate and write the motion; the status line says where, or gives the one-line error."""
        with self._lock, self._reported():
            path = check_save_path(path_text)
            self.doc.to_motion(str(path))
            atomic_write_text(path, self.doc.to_yaml())
            saved = load_motion(str(path), self.description)  # read back as `sim run --policy replay` will
            self._say(f"saved {path.resolve()}: {len(saved.times)} keyframes, {saved.duration:.2f} s, "
                      f"{len(saved.joints)} joints")
            return path
        return None

    # -- display ---------------------------------------------------------------------------------------------
    @contextlib.contextmanager
    def _reported(self):
        """Turn a `ToddlerbotError` into the status line's one-line error (the page stays usable)."""
        try:
            yield
        except ToddlerbotError as exc:
            self._say(f"**error:** {' '.join(str(exc).split())}")

    def _say(self, text: str) -> None:
        self.status.content = text

    def _refresh(self, sliders: bool = True) -> None:
        """Redraw the selected keyframe (robot, balance, table, controls)."""
        doc, i = self.doc, self.current
        pose = doc.poses[i]
        self._quiet = True
        try:
            labels = self._keyframe_labels()
            self.selected.options = labels
            self.selected.value = labels[i]
            self.duration.value = round(doc.durations[i], 3) if i else 0.0
            self.duration.disabled = i == 0
            if sliders:
                for joint, slider in self.sliders.items():
                    slider.value = round(float(np.rad2deg(pose[doc.joint_index(joint)])), 2)
                base = doc.bases[i] or BasePose()
                self.torso_pitch.value = round(float(np.rad2deg(base.pitch)))
                self.torso_roll.value = round(float(np.rad2deg(base.roll)))
        finally:
            self._quiet = False
        data = self.poses.pose(pose, doc.bases[i])
        balance = self.poses.static_balance()
        self.scene.show(data, balance)
        self.balance_view.image = top_view(balance, self.poses.soles(data))
        rows = "\n".join(f"| {'▶' if k == i else ''} {k} | {t:.2f} | {d:.2f} |"
                         for k, (t, d) in enumerate(zip(doc.times, doc.durations)))
        self.table.content = (f"| # | t (s) | duration (s) |\n|---|---|---|\n{rows}\n\n"
                              f"Keyframe {i}: {balance.describe()} ({_torso_words(doc.bases[i])}).")


def _torso_words(base: BasePose | None) -> str:
    if base is None:
        return "standing still, both feet flat"
    height = "resting on the floor" if base.z is None else f"torso {base.z * 1000:.0f} mm high"
    return f"torso at roll {np.rad2deg(base.roll):.0f} deg, pitch {np.rad2deg(base.pitch):.0f} deg, {height}"


def open_editor(description: RobotDescription, keyframes: Keyframes, save_path: Path | None, host: str,
                port: int) -> MotionEditor:
    """Start the page's server (viser serves its own bundled client: nothing is fetched from outside)."""
    server = viser.ViserServer(host=host, port=port, label="ToddlerBot motion editor", verbose=False)
    return MotionEditor(server, description, keyframes, save_path)
