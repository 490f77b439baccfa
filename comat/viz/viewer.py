"""How to look at a recording on this machine (no Rerun import: every ``comat`` command line loads it)."""

from __future__ import annotations

import os
import shlex
import sys

__all__ = ["WEB_VIEWER_URL", "viewer_hint"]

WEB_VIEWER_URL = "http://localhost:9090/?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A9876%2Fproxy"
"""Where ``rerun --serve-web FILE.rrd`` (rerun 0.41) serves a recording: the web viewer on port 9090,
the recording over gRPC on 9876."""


def viewer_hint(path, environ=None) -> str:
    """How to open a recording on this machine: the native viewer where there is a display, else
    the web viewer served over HTTP (with the ssh port forward for a remote machine)."""
    env = os.environ if environ is None else environ
    quoted = shlex.quote(str(path))
    if env.get("DISPLAY") or env.get("WAYLAND_DISPLAY") or sys.platform in ("darwin", "win32"):
        return f"open it with: rerun {quoted}"
    return (
        f"no display here (DISPLAY and WAYLAND_DISPLAY unset): serve it with  rerun --serve-web {quoted}  and open "
        f"{WEB_VIEWER_URL} in a browser (from another machine: ssh -L 9090:localhost:9090 -L 9876:localhost:9876 "
        "HOST first)"
    )
