"""Controller and keyboard input through SDL (pygame): device state -> `TeleopCommand` via the mapping.

Headless machines (and tests) set ``SDL_VIDEODRIVER=dummy``; `open_sdl` does so when no display is present. SDL
reads joysticks without a window; the keyboard needs SDL's event queue, which the dummy driver provides.
"""

from __future__ import annotations

import os

from toddlerbot.errors import ToddlerbotError
from toddlerbot.teleop.gamepad import (
    GamepadMapper,
    GamepadState,
    KeyboardMapper,
    TeleopCommand,
    TeleopMapping,
)


class InputError(ToddlerbotError):
    """No controller, or SDL could not start."""


def open_sdl():
    """Import pygame with SDL's video (dummy without a display) and joystick subsystems started; no audio."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    # The controller keeps working while another window (the viewer, a terminal) has the focus.
    os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
    try:
        import pygame
    except ImportError:
        raise InputError("teleoperation input needs pygame: pip install 'toddlerbot[manip]'") from None
    pygame.display.init()
    pygame.joystick.init()
    return pygame


class JoystickInput:
    """The first (or `index`-th) SDL joystick, read once per control step."""

    def __init__(self, mapping: TeleopMapping, index: int = 0) -> None:
        self.pygame = open_sdl()
        count = self.pygame.joystick.get_count()
        if index >= count:
            raise InputError(f"no game controller at index {index} ({count} connected); use --input keyboard")
        self.joystick = self.pygame.joystick.Joystick(index)
        self.joystick.init()
        self.mapper = GamepadMapper(mapping)

    @property
    def name(self) -> str:
        return self.joystick.get_name()

    def state(self) -> GamepadState:
        self.pygame.event.pump()
        j = self.joystick
        return GamepadState([j.get_axis(i) for i in range(j.get_numaxes())],
                            [j.get_button(i) for i in range(j.get_numbuttons())],
                            [tuple(j.get_hat(i)) for i in range(j.get_numhats())])

    def poll(self) -> TeleopCommand:
        return self.mapper.command(self.state())

    def close(self) -> None:
        self.joystick.quit()


class KeyboardInput:
    """Keys held down (tracked from SDL key events) mapped to the controller's actions."""

    def __init__(self, mapping: TeleopMapping) -> None:
        self.pygame = open_sdl()
        if self.pygame.display.get_surface() is None:
            self.pygame.display.set_mode((320, 80))
            self.pygame.display.set_caption("ToddlerBot teleop (keyboard)")
        self.mapper = KeyboardMapper(mapping)
        self.held: set[str] = set()
        self.quit_requested = False

    def poll(self) -> TeleopCommand:
        pg = self.pygame
        for event in pg.event.get():
            if event.type == pg.KEYDOWN:
                if event.key == pg.K_ESCAPE:
                    self.quit_requested = True
                self.held.add(pg.key.name(event.key))
            elif event.type == pg.KEYUP:
                self.held.discard(pg.key.name(event.key))
            elif event.type == pg.QUIT:
                self.quit_requested = True
        return self.mapper.command(self.held)

    def close(self) -> None:
        self.pygame.display.quit()
