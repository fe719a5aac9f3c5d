#!/usr/bin/env python3
"""Replaces the generated tables in a markdown document with fresh ones.

  splice_report.py DOC OUT_DIR STUDY...

For each STUDY, runs `jointplay report OUT_DIR/STUDY.h5` and puts its output between the lines
`<!-- begin generated: STUDY -->` and `<!-- end generated: STUDY -->` of DOC (appending the block
when the markers are missing). Nothing in the tables is typed by hand. The program is
$JOINTPLAY, default target/release/jointplay.
"""
import os
import subprocess
import sys


def main():
    doc, out, studies = sys.argv[1], sys.argv[2], sys.argv[3:]
    text = open(doc).read()
    for s in studies:
        table = subprocess.run(
            [os.environ.get("JOINTPLAY", "target/release/jointplay"), "report", f"{out}/{s}.h5"],
            check=True, capture_output=True, text=True,
        ).stdout
        begin, end = f"<!-- begin generated: {s} -->", f"<!-- end generated: {s} -->"
        block = f"{begin}\n{table}{end}"
        if begin in text and end in text:
            a = text.index(begin)
            b = text.index(end) + len(end)
            text = text[:a] + block + text[b:]
        else:
            text = text.rstrip("\n") + "\n\n" + block + "\n"
    open(doc, "w").write(text)
    print(f"updated {doc}")


if __name__ == "__main__":
    main()
