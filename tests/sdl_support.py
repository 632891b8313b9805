"""A virtual game controller made by SDL itself (SDL_JoystickAttachVirtual), seen by pygame like a real one."""

from __future__ import annotations

import ctypes
import glob
import os

import pytest

SDL_JOYSTICK_TYPE_GAMECONTROLLER = 1


class VirtualJoystick:
    """Attach a virtual joystick (6 axes, 15 buttons, 1 hat) to pygame's SDL; set its axes/buttons/hat."""

    def __init__(self, pygame, axes: int = 6, buttons: int = 15, hats: int = 1) -> None:
        libs = glob.glob(os.path.join(os.path.dirname(pygame.__file__), "..", "pygame.libs", "libSDL2-2*"))
        if not libs:
            pytest.skip("pygame's bundled SDL2 library not found")
        self.sdl = sdl = ctypes.CDLL(libs[0])
        sdl.SDL_JoystickOpen.restype = ctypes.c_void_p
        sdl.SDL_JoystickSetVirtualAxis.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int16]
        sdl.SDL_JoystickSetVirtualButton.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8]
        sdl.SDL_JoystickSetVirtualHat.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8]
        sdl.SDL_JoystickDetachVirtual.argtypes = [ctypes.c_int]
        self.index = sdl.SDL_JoystickAttachVirtual(SDL_JOYSTICK_TYPE_GAMECONTROLLER, axes, buttons, hats)
        if self.index < 0:
            pytest.skip("SDL could not attach a virtual joystick")
        self.handle = ctypes.c_void_p(sdl.SDL_JoystickOpen(self.index))
        for trigger in (2, 5):  # triggers rest fully released
            self.axis(trigger, -1.0)

    def axis(self, index: int, value: float) -> None:
        """Set an axis to `value` in [-1, 1]."""
        raw = int(max(-32768, min(32767, round(value * 32767 if value >= 0 else value * 32768))))
        assert self.sdl.SDL_JoystickSetVirtualAxis(self.handle, index, raw) == 0

    def button(self, index: int, down: bool) -> None:
        assert self.sdl.SDL_JoystickSetVirtualButton(self.handle, index, int(down)) == 0

    def hat(self, index: int, x: int, y: int) -> None:
        """D-pad: x -1 left / +1 right, y +1 up / -1 down (SDL hat bits: up 1, right 2, down 4, left 8)."""
        bits = (1 if y > 0 else 4 if y < 0 else 0) | (2 if x > 0 else 8 if x < 0 else 0)
        assert self.sdl.SDL_JoystickSetVirtualHat(self.handle, index, bits) == 0

    def detach(self) -> None:
        self.sdl.SDL_JoystickDetachVirtual(self.index)
