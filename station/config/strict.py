"""The model configuration of the [section] models: one policy, set in one place."""

from __future__ import annotations

from pydantic import ConfigDict

# Built on first use (a command validates only its own sections), unknown keys refused,
# frozen, no inf or nan, no coercion (a string is not a number)
STRICT = ConfigDict(defer_build=True, extra="forbid", frozen=True, allow_inf_nan=False,
                    strict=True)
