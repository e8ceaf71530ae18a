"""Change-aware localization of the base: odometry predicts, registration of depth frames against the
surfaces the map trusts corrects (docs/method.md, "State estimation"; docs/design.md, "State estimation").

The estimate is T_world←odom (`Localizer.T_world_odom`): backends keep reporting in their odometry frame and
the loop re-poses states, frames and commands with it. Neither the map nor the controller imports this package.
"""

from core.localization.correction import Correction
from core.localization.health import LocalizationHealth
from core.localization.localizer import Localizer

__all__ = ["Correction", "LocalizationHealth", "Localizer"]
