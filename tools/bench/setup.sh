# The start shared by the benches that run regolith against OpenCV on one campaign; sourced
# (not run) after `root` is set, with the bench's arguments [CAMPAIGN [ENTRY]]. Installs
# opencv-python-headless with pip when `import cv2` fails, builds the CLI (`bin`), makes a work
# folder (`work`, removed on exit), takes CAMPAIGN or makes mini seed 301 from the checked-in
# Mitsuba renders (`campaign`), and compiles it into `$work/db`.

if ! python3 -c 'import cv2, numpy' 2>/dev/null; then
  echo "installing opencv-python-headless (pip) ..." >&2
  python3 -m pip install --quiet opencv-python-headless numpy >&2
fi
(cd "$root" && cargo build --release -q -p regolith-cli)
bin=$root/target/release/regolith

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ $# -ge 1 ]; then
  campaign=$(cd "$1" && pwd)
else
  campaign=$work/campaign
  "$bin" corpus generate --preset mini --seed 301 --renders "$root/corpus/renders" --no-render \
    --out "$campaign" -q
fi

echo "compiling $campaign ..." >&2
"$bin" compile "$campaign" --db "$work/db" -q --json >/dev/null
