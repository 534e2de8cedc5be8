"""The --help layout of the command-line tools (every default shown, descriptions and epilogs as written), and the
options several of them share."""
from __future__ import annotations

import argparse
from typing import Any

from .errors import DEFAULT_FINAL_GUIDANCE_MIN_SPEED, DEFAULT_FINAL_GUIDANCE_SHARE


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """ArgumentDefaultsHelpFormatter without the noise of "(default: None)" on required or unset options."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.required or action.default is None or action.default is False:
            return action.help or ""
        return super()._get_help_string(action)


def add_final_guidance_options(ap: argparse.ArgumentParser) -> None:
    """--final-guidance-share and --final-guidance-min-speed: the model's settings of those names."""
    ap.add_argument("--final-guidance-share", type=float, default=DEFAULT_FINAL_GUIDANCE_SHARE,
                    help="share of the guidance the last denoising step keeps (1: full guidance on every step)")
    ap.add_argument("--final-guidance-min-speed", type=float, default=DEFAULT_FINAL_GUIDANCE_MIN_SPEED,
                    help="ease the last step only for an ego whose history moves at least this fast (m/s)")


def set_final_guidance(model: Any, args: argparse.Namespace) -> dict[str, float]:
    """The two options onto the model, whose setters check them (InputError); returned for a report."""
    model.final_guidance_share = args.final_guidance_share
    model.final_guidance_min_speed = args.final_guidance_min_speed
    return {"final_guidance_share": model.final_guidance_share,
            "final_guidance_min_speed": model.final_guidance_min_speed}


def seeds_option(ap: argparse.ArgumentParser, value: str) -> list[int]:
    """A --seeds value ("0,1,2") as integers; a malformed or empty list exits through `ap.error` with one line."""
    try:
        seeds = [int(x) for x in value.split(",") if x.strip()]
    except ValueError:
        seeds = []
    if not seeds:
        ap.error(f"--seeds must be comma-separated integers, got {value!r}")
    return seeds
