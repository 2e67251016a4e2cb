#!/usr/bin/python3
"""Checks the relative links of README.md and docs/*.md: every linked file
exists, and every #anchor names a heading of the page it points to (GitHub's
rule: lower case, punctuation dropped, spaces to hyphens, repeats numbered).
Prints each broken link as FILE:LINE: LINK: what is wrong; exits 1 if any."""
import os
import re
import sys

root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), '..'))


def anchors(path):
    seen, names, fenced = {}, set(), False
    for line in open(path, encoding='utf-8'):
        if line.startswith('```'):
            fenced = not fenced
        heading = None if fenced else re.match(r'^#{1,6}\s+(.*?)\s*#*\s*$', line)
        if heading:
            slug = re.sub(r'[^\w\- ]', '', heading.group(1).strip().lower()).replace(' ', '-')
            count = seen.get(slug, 0)
            seen[slug] = count + 1
            names.add(slug if count == 0 else f'{slug}-{count}')
    return names


pages = [os.path.join(root, 'README.md')] + sorted(
    os.path.join(root, 'docs', f) for f in os.listdir(os.path.join(root, 'docs')) if f.endswith('.md'))
broken = 0
for page in pages:
    fenced = False
    for number, line in enumerate(open(page, encoding='utf-8'), 1):
        if line.startswith('```'):
            fenced = not fenced
        if fenced:
            continue
        for link in re.findall(r'\]\(([^)\s]+)\)', line):
            if re.match(r'^[a-z]+:', link):
                continue  # http(s), mailto: not checked offline
            path, _, anchor = link.partition('#')
            target = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
            where = f'{os.path.relpath(page, root)}:{number}: {link}'
            if not os.path.exists(target):
                print(f'{where}: no such file {os.path.relpath(target, root)}')
                broken += 1
            elif anchor and target.endswith('.md') and anchor not in anchors(target):
                print(f'{where}: no heading #{anchor} in {os.path.relpath(target, root)}')
                broken += 1
print(f'{len(pages)} pages, {broken} broken links', file=sys.stderr)
sys.exit(1 if broken else 0)
