#!/usr/bin/env python3
"""Checks that a binary of a portable build runs on its baseline CPU: every function that uses
an instruction beyond x86-64-v2 belongs to the instruction level that is allowed it.

A portable build (HAPTICLOTH_PORTABLE) compiles the element pass once per level, each in its own
translation unit at its own -march (server/cloth/simd_level.hpp), and picks one at start-up. The
danger is code of the AVX2 or AVX-512 unit that the rest of the program runs unasked, such as an
inline library function the linker took from that unit; on an older CPU it dies with SIGILL. So
this reads the disassembly (objdump) and fails, naming the functions, if any function outside
hapticloth::cloth::simd_avx2 / simd_avx512 (by name or template argument) uses a VEX or EVEX instruction (AVX, AVX2, FMA, F16C,
AVX-512), a ymm, zmm or mask register, or BMI1/BMI2 (but TZCNT), MOVBE or LZCNT; and if a simd_avx2 function
uses AVX-512.

Usage: tools/portable_isa.py BINARY...   (exit 0: portable; 1: not, with the functions; 2: usage)
"""
import re
import subprocess
import sys

FUNC = re.compile(r"^[0-9a-f]+ <(.*)>:$")
# BMI1/BMI2, MOVBE, LZCNT. Not TZCNT: it is encoded as REP BSF, which a CPU without BMI1 runs as
# BSF (the same result for a non-zero input), and compilers emit it for the baseline on purpose.
BEYOND_V2 = {"andn", "bextr", "blsi", "blsmsk", "blsr", "bzhi", "mulx", "pdep", "pext", "rorx", "sarx",
             "shlx", "shrx", "movbe", "lzcnt"}
# Libraries linked in (the zenoh bridge's Rust crates: memchr, httparse, crc32fast, chacha,
# compiler_builtins; its zstd) that choose their own AVX or BMI2 variant at run time from CPUID,
# and name it so. Never a function of hapticloth's own.
LIBRARY_DISPATCHED = re.compile(r"avx|bmi2|fmaf?_with_fma|^HUF_decompress4X[12]_usingDTable_internal_fast")
LEVEL_NS = {"avx2": "hapticloth::cloth::simd_avx2::", "avx512": "hapticloth::cloth::simd_avx512::"}


def needs(mnemonic, operands):
    """The level an instruction needs: None (x86-64-v2), 'avx2' or 'avx512'."""
    if "%zmm" in operands or re.search(r"%k[0-7]\b", operands) or "{" in operands:
        return "avx512"
    if mnemonic.startswith("v") or "%ymm" in operands or mnemonic in BEYOND_V2:
        return "avx2"
    return None


def check(path):
    p = subprocess.run(["objdump", "-d", "--no-show-raw-insn", "-C", path], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"portable_isa: objdump {path}: {p.stderr.strip()}")
    bad, func, counted = {}, None, 0
    for line in p.stdout.splitlines():
        m = FUNC.match(line)
        if m:
            func = m.group(1)
            counted += 1
            continue
        parts = line.split("\t")
        if func is None or len(parts) < 2:
            continue
        ins = parts[-1].split(None, 1)
        if not ins:
            continue
        # the operands without objdump's comment (# ...) and symbol annotation (<...>)
        operands = re.sub(r"<.*", "", (ins[1] if len(ins) > 1 else "").split("#")[0])
        level = needs(ins[0], operands)
        if level is None:
            continue
        # A function whose name holds a level's namespace (its own, or in its template arguments,
        # which have internal linkage there) is that level's alone.
        allowed = LEVEL_NS["avx512"] in func or (level == "avx2" and LEVEL_NS["avx2"] in func) or (
            "hapticloth::" not in func and LIBRARY_DISPATCHED.search(func) is not None)
        if not allowed:
            bad.setdefault(func, (level, parts[-1].strip()))
    return counted, bad


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    failed = False
    for path in sys.argv[1:]:
        counted, bad = check(path)
        if counted == 0:
            sys.exit(f"portable_isa: {path}: no functions in its disassembly")
        if bad:
            failed = True
            print(f"{path}: {len(bad)} of {counted} functions use instructions beyond x86-64-v2 outside their level:")
            for f, (level, ins) in sorted(bad.items()):
                print(f"  {f}: {ins} ({level})")
        else:
            print(f"{path}: portable ({counted} functions; AVX2 and AVX-512 only in their levels' namespaces)")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
