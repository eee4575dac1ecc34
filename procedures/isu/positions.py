"""Table settings of the calibration positions (Chart II-1 / II-17) from the survey."""

from __future__ import annotations

from procedures.isu.sheets import PositionSetting, ResolverSettings, SurveyResults

# position -> (survey setting it uses, phi3 offset deg, rotating)
_BASE = {
    1: ("1", 0.0), 2: ("1", 180.0), 3: ("3", 0.0), 4: ("3", 180.0), 5: ("5", 0.0), 6: ("5", 180.0),
    7: ("1", 0.0), 8: ("1", 180.0), 9: ("3", 0.0), 10: ("3", 180.0), 11: ("5", 0.0),
    12: ("5", 180.0), 13: ("13", 0.0), 14: ("14", 0.0), 15: ("15", 0.0),
}
# the survey position whose T^BR second column serves each static position
T_BR_OF = {7: 1, 8: 1, 9: 3, 10: 3, 11: 5, 12: 5, 13: 13, 14: 14, 15: 15}


def resolver_settings(survey: SurveyResults) -> ResolverSettings:
    """Chart II-17: positions 1-6 with phi1 = 90 and the rotary axis turning; 7-15 with
    phi1 = 0, phi2 = 90 and bubble-level corrections on phi1 and phi3."""
    out = {}
    for m, (src, off) in _BASE.items():
        phi3, phi4 = survey.settings_deg[src]
        rotating = m <= 6
        out[str(m)] = PositionSetting(
            phi1=90.0 if rotating else 0.0,
            phi2=None if rotating else 90.0,
            phi3=(phi3 + off) % 360.0,
            phi4=phi4,
            bubble_correction=not rotating,
        )
    return ResolverSettings(positions=out)
