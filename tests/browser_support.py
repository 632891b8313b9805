"""Headless Chromium (Debian's `chromium` package, driven by Playwright) and the motion editor as a user runs it.

Playwright's own browser download does not work offline, so the system Chromium is launched with the flags that
keep it from reaching out (background networking, component updates, sync). `.ci/run` installs the package.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager, suppress
from pathlib import Path

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage"]
URL_LINE = re.compile(r"motion editor: (http://\S+)")


def chromium_available() -> bool:
    return Path(CHROMIUM).is_file()


@contextmanager
def browser_page(width: int = 1400, height: int = 900):
    """A page in headless Chromium; `page.external` collects requests that leave this machine."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(120_000)  # a shared 2-core machine renders WebGL in software, slowly
            page.external = []
            page.on("request", lambda r: page.external.append(r.url) if _external(r.url) else None)
            yield page
        finally:
            browser.close()


def _external(url: str) -> bool:
    return not re.match(r"(https?|wss?)://(127\.0\.0\.1|localhost)[:/]|data:|blob:|about:", url)


def _drain(stream, lines: list[str]) -> None:
    try:
        for line in stream:
            lines.append(line)
    except (ValueError, OSError):  # the stream was closed at the end
        pass


@contextmanager
def running_editor(*args: str, timeout_s: float = 120.0):
    """`toddlerbot motion edit ARGS --port 0` in a subprocess; yields (url, process). Stopped with Ctrl-C (SIGINT)
    at the end; the exit code is left on the process for the caller to check."""
    # -X faulthandler: a SIGABRT from the test (below) makes the editor print every thread's stack before it dies
    proc = subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", "toddlerbot.cli.main", "motion", "edit",
                             *args, "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "COLUMNS": "200"},
                            # Ctrl-C reaches it as in a terminal, also when pytest runs as a background job (CI):
                            # a child of one inherits SIGINT ignored, and Python then never raises KeyboardInterrupt
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline, lines = time.monotonic() + timeout_s, []
        url = None
        while url is None:
            line = proc.stdout.readline()
            if not line and (proc.poll() is not None or time.monotonic() > deadline):
                raise RuntimeError(f"the editor did not start: {''.join(lines)}")
            lines.append(line)
            match = URL_LINE.search(line)
            url = match.group(1) if match else None
        # keep reading what the editor prints: a full pipe would block its next print (and its Ctrl-C handling)
        threading.Thread(target=_drain, args=(proc.stdout, lines), daemon=True).start()
        yield url, proc
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            with suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=10)
            time.sleep(0.5)  # the drain thread reads the stacks
            raise AssertionError("the editor was still running 30 s after Ctrl-C; its output and stacks:\n"
                                 + "".join(lines[-200:])) from None
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def labelled(page, label: str, css: str, timeout_s: float = 120.0):
    """The element matching `css` in the row of the control labelled `label` (viser puts a label and its control
    in one flex row; a text input's label does not point at the input)."""
    tag = page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$"))
    tag.first.wait_for(timeout=timeout_s * 1000)
    row = page.locator("div.mantine-Flex-root").filter(has=tag).last
    return row.locator(css).first


def slider(page, joint: str):
    """The thumb of a joint's slider."""
    return labelled(page, joint, '[role="slider"]')


def wait_for_text(page, pattern: str, timeout_s: float = 120.0) -> str:
    """The first text on the page matching the regular expression `pattern`, waiting for it to appear."""
    locator = page.get_by_text(re.compile(pattern)).first
    locator.wait_for(timeout=timeout_s * 1000)
    return locator.inner_text()
