"""Fails if a Catch2 test name holds a ';': CTest splits such names into entries that match no
test and pass without running anything (tests/CMakeLists.txt discovers tests by name)."""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1])
bad = []
for path in sorted(root.rglob("*.cpp")):
    text = path.read_text()
    for match in re.finditer(r'TEST_CASE\(((?:\s*"(?:[^"\\]|\\.)*")+)', text):
        name = "".join(re.findall(r'"((?:[^"\\]|\\.)*)"', match.group(1)))
        if ";" in name:
            line = text.count("\n", 0, match.start()) + 1
            bad.append(f"{path}:{line}: {name}")
if bad:
    sys.exit("test names with ';' (CTest would split them and run nothing):\n" + "\n".join(bad))
print(f"checked the test names under {root}: none holds a ';'")
