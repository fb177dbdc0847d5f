"""Shared test settings: headless pygame, and derandomised hypothesis on CI."""

import os

from hypothesis import settings

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

# CI runs the same examples every time (a failure found locally becomes a regression test);
# locally hypothesis explores new examples on each run.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
