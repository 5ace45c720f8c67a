# Sourced by the foreign-scene tests (foreign_scenes.sh, family_detection.sh): what they share.
#   require_scenes DIR     exit 77 (skip) when DIR is missing, exit 1 under CI=true
#   scene_family SCENE     prints environment.family of SCENE/scene.yaml ("" when absent), read with a
#                          YAML parser (block or flow style: "environment: {family: x, ...}")
#   read_bars FILE         fills the array `args` with the options of a bars file (comments dropped)
require_scenes() {
  if [ ! -d "$1" ]; then
    if [ "${CI:-}" = "true" ]; then echo "foreign scenes folder $1 is missing (CI=true: failure)"; exit 1; fi
    echo "foreign scenes folder $1 is missing: skipped"; exit 77
  fi
}

scene_family() {
  /usr/bin/python3 -c 'import sys, yaml
d = yaml.safe_load(open(sys.argv[1])) or {}
e = d.get("environment") if isinstance(d, dict) else None
print(e.get("family", "") if isinstance(e, dict) else "")' "$1/scene.yaml"
}

read_bars() {
  mapfile -t args < <(grep -v '^[[:space:]]*#' "$1" | tr ' ' '\n' | grep -v '^$')
}
