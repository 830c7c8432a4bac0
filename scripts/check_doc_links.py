#!/usr/bin/env python3
"""Check every relative link in README.md, ARCHITECTURE.md and docs/: the file exists and, for a
#anchor into a Markdown file, a heading with that GitHub slug exists. Usage (from the repository
root): python3 scripts/check_doc_links.py"""
import os, re, sys, glob
root = sys.argv[1] if len(sys.argv) > 1 else "."
files = [f for f in ["README.md", "ARCHITECTURE.md"] + sorted(glob.glob("docs/*.md")) + sorted(glob.glob("docs/**/*.md"))]
files = sorted(set(files))
def strip_code(text):
    out, fence = [], False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"):
            fence = not fence; out.append(""); continue
        out.append("" if fence else re.sub(r"`[^`]*`", "``", line))
    return "\n".join(out)
def slugs(path):
    text = open(path, encoding="utf-8").read()
    seen, res, fence = {}, set(), False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"): fence = not fence; continue
        if fence: continue
        m = re.match(r"^(#{1,6})\s+(.*?)\s*#*\s*$", line)
        if not m: continue
        h = m.group(2)
        h = re.sub(r"!\[[^\]]*\]\([^)]*\)", "", h)
        h = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", h)
        h = h.replace("`", "").lower()
        s = "".join(c for c in h if c.isalnum() or c in " -_").replace(" ", "-")
        n = seen.get(s, 0); seen[s] = n + 1
        res.add(s if n == 0 else f"{s}-{n}")
    return res
bad = 0; count = 0
for f in files:
    raw = open(os.path.join(root, f), encoding="utf-8").read()
    text = strip_code(raw)
    targets = re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", text)
    targets += re.findall(r"<img[^>]*\ssrc=\"([^\"]+)\"", text)
    targets += re.findall(r"^\[[^\]]+\]:\s*(\S+)", text, re.M)
    for t in targets:
        if re.match(r"^[a-z]+:", t): continue
        count += 1
        path, _, anchor = t.partition("#")
        full = os.path.normpath(os.path.join(root, os.path.dirname(f), path)) if path else os.path.join(root, f)
        if not os.path.exists(full):
            print(f"{f}: missing file {t}"); bad += 1; continue
        if anchor and full.endswith(".md") and anchor not in slugs(full):
            print(f"{f}: missing anchor {t}"); bad += 1
print(f"{count} relative links in {len(files)} files, {bad} broken")
sys.exit(1 if bad else 0)
