"""Write the nominal 24-slot GPS constellation as a YUMA almanac (``gps_nominal_24slot.alm``).

Source: *Global Positioning System Standard Positioning Service Performance Standard*,
3rd edition (U.S. Department of Defense, October 2001), Table 3-1 "Reference Orbit Slot
Assignments as of the Defined Epoch" (RAAN and argument of latitude of the 24 slots A1…F4 at
0000Z, 1 July 1993, Greenwich hour angle 18 h 36 min 14.4 s, FK5/J2000) and Table A-2-1
(the same plan in almanac form: e = 0, i = 55°, A = 26 559.7 km, Ω̇ = −4.4874e-7 °/s,
ω = 0). See ``README.md`` beside this file for the conversion.

    python data/gnss/nominal_constellation.py > data/gnss/gps_nominal_24slot.alm
"""

from __future__ import annotations

import math

# slot: (RAAN deg, argument of latitude deg) at the defined epoch (SPS PS 2001, Table 3-1)
SLOTS = {
    "A1": (272.847, 268.126), "A2": (272.847, 161.786), "A3": (272.847, 11.676),
    "A4": (272.847, 41.806), "B1": (332.847, 80.956), "B2": (332.847, 173.336),
    "B3": (332.847, 309.976), "B4": (332.847, 204.376), "C1": (32.847, 111.876),
    "C2": (32.847, 11.796), "C3": (32.847, 339.666), "C4": (32.847, 241.556),
    "D1": (92.847, 135.226), "D2": (92.847, 265.446), "D3": (92.847, 35.156),
    "D4": (92.847, 167.356), "E1": (152.847, 197.046), "E2": (152.847, 302.596),
    "E3": (152.847, 66.066), "E4": (152.847, 333.686), "F1": (212.847, 238.886),
    "F2": (212.847, 345.226), "F3": (212.847, 105.206), "F4": (212.847, 135.346),
}  # fmt: skip
GREENWICH_HOUR_ANGLE_DEG = 15.0 * (18 + 36 / 60 + 14.4 / 3600)
WEEK = 703  # 1993-06-27 is the start of GPS week 703
TOA_S = 4 * 86400 + 9  # Thursday 0000Z 1 July 1993 in GPS time (GPS − UTC = 9 s that day)
SEMI_MAJOR_AXIS_M = 26_559.7e3
INCLINATION_DEG = 55.0
NODE_RATE_RAD_S = math.radians(-4.4874e-7)
EARTH_ROTATION_RAD_S = 7.2921151467e-5  # IS-GPS-200


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2 * math.pi)


def yuma_text() -> str:
    """The YUMA almanac of the 24 slots, PRN 1…24 in slot order A1…F4."""
    records = []
    for prn, (raan, latitude_arg) in enumerate(SLOTS.values(), start=1):
        # Longitude of the node at toa = RAAN − GHA; YUMA's Ω0 is referred to the week start:
        # Ω(t) = Ω0 + (Ω̇ − Ω̇e) tk − Ω̇e toa  (IS-GPS-200 Table 20-IV).
        node = math.radians(raan - GREENWICH_HOUR_ANGLE_DEG) + EARTH_ROTATION_RAD_S * TOA_S
        records.append(
            f"******** Week {WEEK} almanac for PRN-{prn:02d} ********\n"
            f"ID:                         {prn:02d}\n"
            f"Health:                     000\n"
            f"Eccentricity:               {0.0:.10E}\n"
            f"Time of Applicability(s):  {TOA_S:.4f}\n"
            f"Orbital Inclination(rad):   {math.radians(INCLINATION_DEG):.10f}\n"
            f"Rate of Right Ascen(r/s):  {NODE_RATE_RAD_S:.10E}\n"
            f"SQRT(A)  (m 1/2):           {math.sqrt(SEMI_MAJOR_AXIS_M):.6f}\n"
            f"Right Ascen at Week(rad):   {_wrap(node):.10E}\n"
            f"Argument of Perigee(rad):   {0.0:.9f}\n"
            f"Mean Anom(rad):             {_wrap(math.radians(latitude_arg)):.10E}\n"
            f"Af0(s):                     {0.0:.10E}\n"
            f"Af1(s/s):                   {0.0:.10E}\n"
            f"week:                        {WEEK}\n"
        )
    return "\n".join(records) + "\n"


if __name__ == "__main__":
    print(yuma_text(), end="")
