# The start shared by every bench on one campaign; sourced (not run) after `root` is set, with
# the bench's arguments [CAMPAIGN ...]. Builds the CLI (`bin`), makes a work folder (`work`,
# removed on exit) and takes CAMPAIGN or makes mini seed 301 from the checked-in Mitsuba
# renders (`campaign`).

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
