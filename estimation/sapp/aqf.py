"""The SAPP Attitude Quality Flag (Ali et al. 2005, sec. 2.1).

The flag says how *complete* the attitude estimate is, not how accurate. Its four values,
from worst to best: Unknown (not to be trusted; the value after landing), TiltOnly (good
for tilt only), Coarse (complete but crude), Fine (complete and good enough to point the
HGA). Members compare by that order, so ``aqf >= AttitudeQuality.COARSE`` reads as the
paper's "Coarse or better" (the MTES example of sec. 2.1).

>>> AttitudeQuality.TILT_ONLY < AttitudeQuality.COARSE
True
>>> max(AttitudeQuality.FINE, AttitudeQuality.UNKNOWN).paper_name
'Fine'
"""

from __future__ import annotations

import enum


class AttitudeQuality(enum.Enum):
    """Attitude Quality Flag; the value is the rank, 0 = worst (Ali et al. 2005, sec. 2.1)."""

    UNKNOWN = 0
    TILT_ONLY = 1
    COARSE = 2
    FINE = 3

    @property
    def paper_name(self) -> str:
        """The flag's name as the paper spells it: ``Unknown``, ``TiltOnly``, ...

        >>> AttitudeQuality.TILT_ONLY.paper_name
        'TiltOnly'
        """
        return _PAPER_NAMES[self]

    def __lt__(self, other: object) -> bool:
        if not isinstance(other, AttitudeQuality):
            return NotImplemented
        return self.value < other.value

    def __le__(self, other: object) -> bool:
        if not isinstance(other, AttitudeQuality):
            return NotImplemented
        return self.value <= other.value

    def __gt__(self, other: object) -> bool:
        if not isinstance(other, AttitudeQuality):
            return NotImplemented
        return self.value > other.value

    def __ge__(self, other: object) -> bool:
        if not isinstance(other, AttitudeQuality):
            return NotImplemented
        return self.value >= other.value


_PAPER_NAMES = {
    AttitudeQuality.UNKNOWN: "Unknown",
    AttitudeQuality.TILT_ONLY: "TiltOnly",
    AttitudeQuality.COARSE: "Coarse",
    AttitudeQuality.FINE: "Fine",
}
