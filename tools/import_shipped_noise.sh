#!/usr/bin/env bash
# Re-import the darktable noise of every shipped profile (configs/sensors/) with the default
# negative-b rule (read-noise floor, docs/noise.md), so each provenance.noise is the importer's
# own text. Run from the repository root with ../shared/data present; then check `git diff`.
# The composite phone profile is created from scratch (noise, then colour) when it is missing.
set -euo pipefail
CSV=../shared/data/noise/darktable_noiseprofiles.csv
BIN=${BIN:-target/release/hdrsynth}
[ -f "$CSV" ] || { echo "missing $CSV" >&2; exit 1; }
imp() { "$BIN" profile import-darktable --csv "$CSV" "$@"; }

imp --maker Canon --model "EOS 550D" --set 1 --black 2056 --white 15000 --bits 14 \
  --levels-source "BlackLevel/WhiteLevel/BitsPerSample tags of a real Canon EOS 550D (Kiss X4) raw DNG: ../shared/data/real_raw/colorchart.dng (syoyo/tinydng @ 40a4dde, MIT), read by hdrsynth's DNG reader" \
  --out configs/sensors/canon_eos_550d.toml
imp --maker Samsung --model NX1000 --black 0 --white 4095 --bits 12 \
  --levels-source 'rawspeed data/cameras.xml (kmilos/rawspeed @ 16dd3e8b): <Camera make="SAMSUNG" model="NX1000"> black="0" white="4095"; 12-bit raw' \
  --out configs/sensors/samsung_nx1000.toml
imp --maker Samsung --model WB2000 --black 0 --white 4000 --bits 12 \
  --levels-source 'rawspeed data/cameras.xml (kmilos/rawspeed @ 16dd3e8b): <Camera make="SAMSUNG" model="WB2000"> <Sensor black="0" white="4000"/>; 12-bit raw (LibRaw colordata.cpp maximum 0xfff)' \
  --out configs/sensors/samsung_wb2000.toml

PHONE=configs/sensors/composite_phone.toml
imp --maker OnePlus --model "ONEPLUS A6003" --black 64 --white 1023 --bits 10 --kind composite \
  --name "Composite phone (OnePlus 6 noise, Galaxy S9 colour)" \
  --levels-source "assumed, not read from a raw file of either phone: the usual 10-bit phone raw (Android RAW10 / RAW_SENSOR) with a 64 DN pedestal and white at 2^10 − 1 = 1023; LibRaw colordata.cpp gives no levels for the Galaxy S9 (t_black 0, t_maximum 0: taken from each file)" \
  --out "$PHONE"
"$BIN" profile colour-from-matrix --matrix 13292,-6142,-1268,-4095,12890,1283,-557,1930,5163 \
  --source 'Adobe DNG Converter ColorMatrix for Samsung Galaxy S9 / S9+ (XYZ D65 → camera) as tabulated in LibRaw src/tables/colordata.cpp (LibRaw/LibRaw @ 158e635e, adobe_coeff entry "Galaxy S9"; the same matrix is listed for "Galaxy Note 9 Rear Camera")' \
  --out "$PHONE"
# provenance.response ("assumption, not measured: ... sRGB ...") and provenance.notes of the
# composite profile were written by hand after its creation; re-imports keep them.

# A second, independent phone-class target (held-out checks, docs/experiments.md).
PHONE_B=configs/sensors/composite_phone_b.toml
imp --maker LGE --model "Nexus 5X" --black 66 --white 1023 --bits 10 --kind composite \
  --name "Composite phone B (Nexus 5X noise, IMX219 colour)" \
  --levels-source 'LibRaw src/tables/colordata.cpp (LibRaw/LibRaw @ 158e635e), adobe_coeff entry Broadcom "RPi IMX219": t_black 66, t_maximum 0x3ff (10-bit raw); not read from a Nexus 5X raw file' \
  --out "$PHONE_B"
"$BIN" profile colour-from-matrix --matrix 5302,1083,-728,-5320,14112,1699,-863,2371,5136 \
  --source 'LibRaw colour matrix (XYZ D65 → camera) for the Sony IMX219 phone-class sensor, LibRaw src/tables/colordata.cpp (LibRaw/LibRaw @ 158e635e), adobe_coeff entry Broadcom "RPi IMX219" (marked /* LibRaw */: measured by LibRaw, not Adobe)' \
  --out "$PHONE_B"
# provenance.notes of composite_phone_b.toml was written by hand after its creation.
