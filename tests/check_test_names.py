"""Fails if a Catch2 test name holds a ';': CTest splits such names into entries that match no
test and pass without running anything (tests/CMakeLists.txt discovers tests by name).

Also fails on names over 100 characters and on names that carry a session number or a version
tag (like 0.12.0): a name says what the test checks; the details go in a comment above it."""
import pathlib
import re
import sys

MAX_LENGTH = 100
RULES = [
    ("test names with ';' (CTest would split them and run nothing)", lambda name: ";" in name),
    (f"test names over {MAX_LENGTH} characters (move the details to a comment above the test)",
     lambda name: len(name) > MAX_LENGTH),
    ("test names with a session number or a version tag (say what is checked, not when)",
     lambda name: re.search(r"session|\bv?\d+\.\d+\.\d+", name, re.IGNORECASE) is not None),
]

root = pathlib.Path(sys.argv[1])
bad = {title: [] for title, _ in RULES}
for path in sorted(root.rglob("*.cpp")):
    text = path.read_text()
    for match in re.finditer(r'TEST_CASE\(((?:\s*"(?:[^"\\]|\\.)*")+)', text):
        name = "".join(re.findall(r'"((?:[^"\\]|\\.)*)"', match.group(1)))
        line = text.count("\n", 0, match.start()) + 1
        for title, broken in RULES:
            if broken(name):
                bad[title].append(f"{path}:{line}: {name}")
if any(bad.values()):
    sys.exit("\n".join(f"{title}:\n" + "\n".join(found) for title, found in bad.items() if found))
print(f"checked the test names under {root}: none holds a ';', is over {MAX_LENGTH} characters "
      "or carries a session number or version tag")
