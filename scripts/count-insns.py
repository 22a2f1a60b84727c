#!/usr/bin/env python3
"""Counts the guest instructions a program executed, from qemu's log on standard input.

Run the program as `qemu-ARCH -d in_asm,exec,nochain -D /dev/stdout PROGRAM ... | count-insns.py`:
`in_asm` prints each translation block once, an instruction a line, when it is translated;
`exec` with `nochain` prints a line each time a block runs. The count is the sum over the
blocks of (times run) × (instructions in it). Other lines (the program's own output) are
ignored. Prints JSON: {"instructions": N, "blocks_run": M, "unknown_blocks": K}.
"""
import json
import sys


def main() -> None:
    sizes: dict[str, int] = {}
    runs: dict[str, int] = {}
    current = None
    for line in sys.stdin:
        if line.startswith("Trace "):
            # Trace 0: 0xHOST [FLAGS/GUEST_PC/...] symbol
            at = line.find("[")
            if at < 0:
                continue
            pc = line[at + 1 :].split("/")[1]
            runs[pc] = runs.get(pc, 0) + 1
        elif line.startswith("IN:"):
            current = None
        elif line.startswith("0x") and ":  " in line[:24]:
            addr = line[2 : line.index(":")].rjust(16, "0")
            if current is None:
                current = addr
                sizes[current] = 0
            sizes[current] += 1
        elif not line.strip():
            current = None
    total = sum(n * sizes[pc] for pc, n in runs.items() if pc in sizes)
    unknown = sum(n for pc, n in runs.items() if pc not in sizes)
    print(json.dumps({"instructions": total, "blocks_run": sum(runs.values()), "unknown_blocks": unknown}))


if __name__ == "__main__":
    main()
