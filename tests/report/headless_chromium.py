"""Headless Chromium for the report's browser tests: finding it (skip or fail when absent) and its offline command line.

``browser`` fails where Chromium could be installed (root with apt-get: ``bash install.sh --test``
installs it) and skips only where it cannot; ``offline_command`` sends every network request to a
closed port, so a page that fetches anything shows it.
"""

from __future__ import annotations

import os
import shutil

import pytest

BROWSERS = ("chromium", "chromium-browser", "google-chrome")


def browser() -> str:
    """The path of a Chromium on PATH; fails when it is absent but installable here, else skips."""
    found = next((path for name in BROWSERS if (path := shutil.which(name))), None)
    if found:
        return found
    if os.geteuid() == 0 and shutil.which("apt-get"):
        pytest.fail("chromium is not installed though it can be (root, apt-get): run `bash install.sh --test`")
    pytest.skip("chromium is not installed and cannot be installed here (not root or no apt-get)")


def offline_command(user_dir, size: tuple[int, int], budget_ms: int) -> list[str]:
    """Headless Chromium's command line up to its output option: no network, a window of ``size`` (width, height)."""
    return [
        browser(), "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
        "--proxy-server=127.0.0.1:9", f"--user-data-dir={user_dir}", f"--window-size={size[0]},{size[1]}",
        f"--virtual-time-budget={budget_ms}",
    ]  # fmt: skip
