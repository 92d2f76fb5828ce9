"""Repack Mitsuba's wheel down to the variants a GPU check uses (issue 44, 2026-12-03).

    python tools/repack_wheel.py WHEEL OUTDIR [--variants cuda_ad_rgb,llvm_ad_rgb]

mitsuba 3.9.1's wheel (62.6 MB) holds thirteen variants, each a Python extension module
(``mitsuba/<variant>.cpython-*.so``, 0.5 to 1.3 MB compressed) beside the code they share
(``libmitsuba.so``, Embree, OpenEXR, the plugins, which hold every variant). The repack keeps
the shared code and the variants named, and leaves out:

- the other variants' extension modules,
- the spectral upsampling table ``mitsuba/data/srgb.coeff`` (8.9 MB) when no spectral
  variant is kept (RGB variants render without it: the test installs the repack and renders),
- the C++ headers, CMake and pkg-config files (``mitsuba/include``, ``cmake``, ``pkgconfig``),
  which only a build against Mitsuba reads.

``mitsuba/config.py`` then lists only the kept variants (``mi.variants()``), the version gets
the local label ``+rgb`` (pip still takes it for ``mitsuba==3.9.1``), and RECORD is written
again with every kept file's hash and size, so that pip installs the repack as any wheel.
Prints the new wheel's path. Exit 1 with one line on stderr when the wheel is not what it
expects (not a wheel, a variant asked for that it lacks).
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import os
import re
import sys
import zipfile

#: a variant's extension module at the top of the package
VARIANT_MODULE = re.compile(r"^mitsuba/((?:scalar|llvm|cuda)_[a-z_]+)\.cpython-[^/]+\.so$")
#: folders only a build against Mitsuba reads
BUILD_ONLY = ("mitsuba/include/", "mitsuba/cmake/", "mitsuba/pkgconfig/")
SPECTRAL_TABLE = "mitsuba/data/srgb.coeff"
LOCAL_LABEL = "rgb"


class RepackError(Exception):
    pass


def record_hash(data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=")
    return "sha256=" + digest.decode("ascii")


def repack(wheel: str, outdir: str, keep: list) -> str:
    name = os.path.basename(wheel)
    m = re.match(r"^(mitsuba)-([^-]+)-(.+)\.whl$", name)
    if not m:
        raise RepackError(f"{name}: not a mitsuba wheel file name (mitsuba-VERSION-TAGS.whl)")
    dist, version, tags = m.groups()
    try:
        zin = zipfile.ZipFile(wheel)
    except (OSError, zipfile.BadZipFile) as exc:
        raise RepackError(f"{wheel}: not a readable wheel ({exc})") from None
    names = zin.namelist()
    info_dir = f"{dist}-{version}.dist-info/"
    if info_dir + "RECORD" not in names:
        raise RepackError(f"{name}: no {info_dir}RECORD inside")
    present = {VARIANT_MODULE.match(n).group(1) for n in names if VARIANT_MODULE.match(n)}
    missing = [v for v in keep if v not in present]
    if missing:
        raise RepackError(f"{name}: no variant {', '.join(missing)} inside "
                          f"(it has {', '.join(sorted(present))})")
    spectral = any("spectral" in v for v in keep)

    def kept(n: str) -> bool:
        v = VARIANT_MODULE.match(n)
        if v:
            return v.group(1) in keep
        if n.startswith(BUILD_ONLY) or n.endswith("/"):
            return False
        if n == SPECTRAL_TABLE:
            return spectral
        return n != info_dir + "RECORD"

    new_version = f"{version.split('+')[0]}+{LOCAL_LABEL}"
    new_info = f"{dist}-{new_version}.dist-info/"
    out_path = os.path.join(outdir, f"{dist}-{new_version}-{tags}.whl")
    tmp_path = out_path + ".part"
    records = []
    with zipfile.ZipFile(tmp_path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zout:
        for item in zin.infolist():
            if not kept(item.filename):
                continue
            data = zin.read(item)
            target = item.filename
            if target.startswith(info_dir):
                target = new_info + target[len(info_dir):]
            if target == new_info + "METADATA":
                data = re.sub(rb"(?m)^Version: .*$", f"Version: {new_version}".encode(), data,
                              count=1)
            elif target == "mitsuba/config.py":
                data, n = re.subn(rb"(?m)^MI_VARIANTS = .*$",
                                  f"MI_VARIANTS = {keep!r}".encode(), data, count=1)
                if n != 1:
                    raise RepackError(f"{name}: mitsuba/config.py has no MI_VARIANTS line")
                data = (b"# Repacked by dopplertof's tools/repack_wheel.py (issue 44): only the "
                        b"variants in MI_VARIANTS\n" + data)
            info = zipfile.ZipInfo(target, date_time=item.date_time)
            info.external_attr = item.external_attr
            info.compress_type = zipfile.ZIP_DEFLATED
            zout.writestr(info, data, compress_type=zipfile.ZIP_DEFLATED, compresslevel=9)
            records.append(f"{target},{record_hash(data)},{len(data)}")
        records.append(f"{new_info}RECORD,,")
        zout.writestr(zipfile.ZipInfo(new_info + "RECORD", date_time=(2026, 12, 3, 0, 0, 0)),
                      "\n".join(records) + "\n", compress_type=zipfile.ZIP_DEFLATED)
    os.replace(tmp_path, out_path)
    return out_path


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("wheel")
    p.add_argument("outdir")
    p.add_argument("--variants", default="cuda_ad_rgb,llvm_ad_rgb",
                   help="comma-separated variants to keep (default: %(default)s)")
    args = p.parse_args()
    keep = [v for v in args.variants.split(",") if v]
    try:
        if not os.path.isdir(args.outdir):
            raise RepackError(f"{args.outdir}: no such folder")
        print(repack(args.wheel, args.outdir, keep))
    except RepackError as exc:
        print(f"repack_wheel.py: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
