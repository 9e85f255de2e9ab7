# The start shared by the benches that run regolith against OpenCV on one campaign; sourced
# (not run) after `root` is set, with the bench's arguments [CAMPAIGN [ENTRY]]. Installs
# opencv-python-headless with pip when `import cv2` fails, takes the campaign as
# `campaign.sh` does (`bin`, `work`, `campaign`) and compiles it into `$work/db`.

if ! python3 -c 'import cv2, numpy' 2>/dev/null; then
  echo "installing opencv-python-headless (pip) ..." >&2
  python3 -m pip install --quiet opencv-python-headless numpy >&2
fi
source "$root/tools/bench/campaign.sh"

echo "compiling $campaign ..." >&2
"$bin" compile "$campaign" --db "$work/db" -q --json >/dev/null
