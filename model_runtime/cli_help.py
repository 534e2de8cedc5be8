"""The --help layout of the command-line tools: every default shown, descriptions and epilogs as written."""
from __future__ import annotations

import argparse


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """ArgumentDefaultsHelpFormatter without the noise of "(default: None)" on required or unset options."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.required or action.default is None or action.default is False:
            return action.help or ""
        return super()._get_help_string(action)
