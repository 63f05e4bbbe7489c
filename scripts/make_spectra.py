#!/usr/bin/env python3
"""Writes the default spectra of assets/spectra/ from analytic models.

Every curve here is a documented model with stated parameters, not a measurement: no
measured spectrum of the ChromaTouch LEDs, dyes, coating or camera is public. The models and
the reasons for their parameters are in assets/spectra/README.md; the parameters are the
constants below. Replace a file by a measured curve in the same CSV format (README) and the
renderer takes it as is.

Usage (from the repository root):
    python3 scripts/make_spectra.py            # rewrite assets/spectra/*.csv
    python3 scripts/make_spectra.py --check    # exit 1 if a committed file differs
    python3 scripts/make_spectra.py --out DIR  # write somewhere else
    python3 scripts/make_spectra.py --describe # LED chromaticity and CCT, peak wavelengths

Only the Python 3 standard library is used, so the output is the same wherever Python's
correctly rounded float formatting and a C library exp() agree to the printed digits.
"""

import argparse
import math
import pathlib
import sys

# Tabulation: 380 to 730 nm every 5 nm (71 rows), the grid of render/spectrum.hpp's range.
# The renderer resamples to its own 1 nm grid by linear interpolation.
LAMBDA_MIN_NM = 380
LAMBDA_MAX_NM = 730
STEP_NM = 5

# ---- White LED (phosphor-converted: blue InGaN die + YAG:Ce phosphor) -----------------------
LED_BLUE_PEAK_NM = 450.0  # InGaN die emission peak
LED_BLUE_FWHM_NM = 20.0  # Gaussian full width at half maximum
LED_PHOSPHOR_PEAK_NM = 555.0  # YAG:Ce band maximum
LED_PHOSPHOR_HWHM_SHORT_NM = 45.0  # half width at half maximum on the blue side
LED_PHOSPHOR_HWHM_LONG_NM = 70.0  # on the red side (the band's long red tail)
LED_PHOSPHOR_HEIGHT = 0.55  # band maximum relative to the blue peak (cool white)

# ---- Camera: generic CMOS Bayer sensor behind an IR-cut filter ------------------------------
# Colour filter x silicon response of each channel: a two-sided Gaussian
# (peak nm, sigma on the short side nm, sigma on the long side nm, peak height).
CAMERA_CHANNELS = {
    "r": (610.0, 20.0, 50.0, 0.90),
    "g": (535.0, 30.0, 32.0, 1.00),
    "b": (455.0, 18.0, 28.0, 0.85),
}
CAMERA_CROSSTALK = 0.01  # floor of every colour filter's transmission (leak), relative
CAMERA_IR_CUT_50_NM = 650.0  # IR-cut filter: 50 % transmission
CAMERA_IR_CUT_WIDTH_NM = 5.0  # logistic width: 10 % to 90 % over 2 ln 9 x 5 = 22 nm
CAMERA_UV_EDGE_50_NM = 400.0  # lens glass and silicon: response halves at 400 nm
CAMERA_UV_EDGE_WIDTH_NM = 8.0

# ---- Inner markers: magenta filter dye, absorption coefficient in 1/mm ----------------------
# Baseline + one Gaussian band (absorbs green, transmits blue and red).
MAGENTA_BASE_PER_MM = 0.10
MAGENTA_PEAK_PER_MM = 10.0
MAGENTA_PEAK_NM = 528.0
MAGENTA_SIGMA_NM = 20.0

# ---- Outer markers: cyan dye --------------------------------------------------------------
# Absorption: baseline + one two-sided Gaussian band (absorbs red).
CYAN_BASE_PER_MM = 0.15
CYAN_PEAK_PER_MM = 12.0
CYAN_PEAK_NM = 640.0
CYAN_SIGMA_SHORT_NM = 25.0
CYAN_SIGMA_LONG_NM = 50.0
# Diffuse albedo of the dyed, scattering marker: high in blue-green, low in red, a logistic
# step between (albedo = low + (high - low) / (1 + exp((lambda - edge) / width))).
CYAN_ALBEDO_HIGH = 0.78
CYAN_ALBEDO_LOW = 0.04
CYAN_ALBEDO_EDGE_NM = 573.0
CYAN_ALBEDO_WIDTH_NM = 8.0

# ---- White coating: TiO2-pigmented silicone, diffuse albedo ---------------------------------
# Flat plateau with the pigment's absorption edge in the violet:
# albedo = plateau - drop / (1 + exp((lambda - edge) / width)).
COATING_PLATEAU = 0.85
COATING_DROP = 0.25
COATING_EDGE_NM = 410.0
COATING_WIDTH_NM = 12.0


def wavelengths():
    return list(range(LAMBDA_MIN_NM, LAMBDA_MAX_NM + 1, STEP_NM))


def gaussian(lam, peak, sigma):
    return math.exp(-0.5 * ((lam - peak) / sigma) ** 2)


def two_sided_gaussian(lam, peak, sigma_short, sigma_long):
    return gaussian(lam, peak, sigma_short if lam < peak else sigma_long)


def logistic(x):
    return 1.0 / (1.0 + math.exp(-x))


def fwhm_to_sigma(fwhm):
    return fwhm / (2.0 * math.sqrt(2.0 * math.log(2.0)))


def led_white(lam):
    blue = gaussian(lam, LED_BLUE_PEAK_NM, fwhm_to_sigma(LED_BLUE_FWHM_NM))
    phosphor = LED_PHOSPHOR_HEIGHT * two_sided_gaussian(
        lam,
        LED_PHOSPHOR_PEAK_NM,
        fwhm_to_sigma(2.0 * LED_PHOSPHOR_HWHM_SHORT_NM),
        fwhm_to_sigma(2.0 * LED_PHOSPHOR_HWHM_LONG_NM),
    )
    return blue + phosphor


def camera(lam, channel):
    peak, sigma_short, sigma_long, height = CAMERA_CHANNELS[channel]
    colour_filter = CAMERA_CROSSTALK + height * two_sided_gaussian(
        lam, peak, sigma_short, sigma_long
    )
    ir_cut = logistic(-(lam - CAMERA_IR_CUT_50_NM) / CAMERA_IR_CUT_WIDTH_NM)
    uv_edge = logistic((lam - CAMERA_UV_EDGE_50_NM) / CAMERA_UV_EDGE_WIDTH_NM)
    return colour_filter * ir_cut * uv_edge


def magenta_absorption(lam):
    return MAGENTA_BASE_PER_MM + MAGENTA_PEAK_PER_MM * gaussian(
        lam, MAGENTA_PEAK_NM, MAGENTA_SIGMA_NM
    )


def cyan_absorption(lam):
    return CYAN_BASE_PER_MM + CYAN_PEAK_PER_MM * two_sided_gaussian(
        lam, CYAN_PEAK_NM, CYAN_SIGMA_SHORT_NM, CYAN_SIGMA_LONG_NM
    )


def cyan_albedo(lam):
    step = logistic(-(lam - CYAN_ALBEDO_EDGE_NM) / CYAN_ALBEDO_WIDTH_NM)
    return CYAN_ALBEDO_LOW + (CYAN_ALBEDO_HIGH - CYAN_ALBEDO_LOW) * step


def coating_albedo(lam):
    return COATING_PLATEAU - COATING_DROP * logistic(-(lam - COATING_EDGE_NM) / COATING_WIDTH_NM)


def fmt(value):
    """Six decimals, no negative zero: stable text for byte-for-byte comparison."""
    text = f"{value:.6f}"
    return "0.000000" if text == "-0.000000" else text


def table(header, columns):
    lines = [",".join(header)]
    for lam in wavelengths():
        lines.append(",".join([str(lam)] + [fmt(f(lam)) for f in columns]))
    return "\n".join(lines) + "\n"


def files():
    """File name -> text of every generated CSV."""
    return {
        "led_white.csv": table(["wavelength_nm", "relative_emission"], [led_white]),
        "camera_rgb.csv": table(
            ["wavelength_nm", "r", "g", "b"],
            [lambda l, c=c: camera(l, c) for c in ("r", "g", "b")],
        ),
        "inner_marker_magenta.csv": table(
            ["wavelength_nm", "absorption_per_mm"], [magenta_absorption]
        ),
        "outer_marker_cyan.csv": table(["wavelength_nm", "absorption_per_mm"], [cyan_absorption]),
        "outer_marker_cyan_albedo.csv": table(["wavelength_nm", "albedo"], [cyan_albedo]),
        "coating_white.csv": table(["wavelength_nm", "albedo"], [coating_albedo]),
    }


# ---- Description (--describe): numbers quoted in assets/spectra/README.md -------------------
# CIE 1931 2-degree colour-matching functions by the multi-lobe analytic fit of Wyman, Sloan
# and Shirley 2013 ("Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
# JCGT 2(2)), good to about 0.01 in chromaticity: enough to say what white the LED model is.
def _cie_xyz(lam):
    def g(mu, s1, s2):
        return two_sided_gaussian(lam, mu, s1, s2)

    x = 1.056 * g(599.8, 37.9, 31.0) + 0.362 * g(442.0, 16.0, 26.7) - 0.065 * g(501.1, 20.4, 26.2)
    y = 0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1)
    z = 1.217 * g(437.0, 11.8, 36.0) + 0.681 * g(459.0, 26.0, 13.8)
    return x, y, z


def describe():
    X = Y = Z = 0.0
    for lam in range(LAMBDA_MIN_NM, LAMBDA_MAX_NM + 1):
        e = led_white(lam)
        x, y, z = _cie_xyz(lam)
        X, Y, Z = X + e * x, Y + e * y, Z + e * z
    cx, cy = X / (X + Y + Z), Y / (X + Y + Z)
    n = (cx - 0.3320) / (0.1858 - cy)  # McCamy 1992 correlated colour temperature
    cct = 449.0 * n**3 + 3525.0 * n**2 + 6823.3 * n + 5520.33
    print(f"led_white: CIE 1931 x = {cx:.4f}, y = {cy:.4f}, CCT about {cct:.0f} K (McCamy)")
    for name, f in [
        ("led_white", led_white),
        ("camera r", lambda l: camera(l, "r")),
        ("camera g", lambda l: camera(l, "g")),
        ("camera b", lambda l: camera(l, "b")),
        ("inner_marker_magenta", magenta_absorption),
        ("outer_marker_cyan", cyan_absorption),
    ]:
        peak = max(range(LAMBDA_MIN_NM, LAMBDA_MAX_NM + 1), key=f)
        print(f"{name}: maximum {f(peak):.4f} at {peak} nm")


def main():
    repo = pathlib.Path(__file__).resolve().parent.parent
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=pathlib.Path, default=repo / "assets" / "spectra")
    parser.add_argument("--check", action="store_true", help="compare instead of writing")
    parser.add_argument("--describe", action="store_true", help="print the models' key numbers")
    args = parser.parse_args()
    if args.describe:
        describe()
        return 0

    differing = []
    for name, text in files().items():
        path = args.out / name
        if args.check:
            if not path.is_file() or path.read_bytes() != text.encode("ascii"):
                differing.append(str(path))
        else:
            args.out.mkdir(parents=True, exist_ok=True)
            path.write_bytes(text.encode("ascii"))
            print(f"wrote {path}")
    if differing:
        print("differs from scripts/make_spectra.py: " + ", ".join(differing), file=sys.stderr)
        return 1
    if args.check:
        print("all spectra match scripts/make_spectra.py")
    return 0


if __name__ == "__main__":
    sys.exit(main())
