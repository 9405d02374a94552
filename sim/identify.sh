#!/bin/sh
# make sim's identification (mk/sim.mk, IDENTIFY=1; docs/identify.md): the
# path a user follows to calibrate the robot as built instead of the robot as
# described, on the bench's perturbed robot.
#
#   1. survey: the firmware's `survey` (every tendon pulled alone, its
#      samples streamed: hallhome.op_survey turns the console log into the
#      pulls), and one weight per segment hung by the bench (hh_bench
#      --survey --survey-weight: the bench cannot hang a weight when a host
#      asks); should the board's survey not complete, the bench's own
#      stepped pulls stand in, announced
#   2. identify: hallhome identify fit ROBOT.toml SURVEY.json -> <robot>_id.toml
#   3. table: hallhome tables <robot>_id.toml
#   4. firmware: make firmware ROBOT=<robot>_id (its own build directory)
#
# Step 5, the calibration, is make sim's own. Each step's output is kept in
# OUT (one directory per robot, seed and perturbation) and reused while it is
# newer than what it was made from, so running a seed again costs nothing
# here. The identified robot's table is copied into TABLES only when it
# changed: the firmware build directory is shared by every seed of a robot,
# and a table with an older time stamp than its object would not be rebuilt.
#
# usage: sim/identify.sh ROBOT_TOML PLANT SEED OUT TABLES [hh_bench options: the
# perturbation, --survey-weight-all]
# environment: BENCH (hh_bench), FW_ELF (the robot's firmware with its nominal
# table: it runs the survey), PY (the venv's python), WEIGHT_G (grams per
# segment, 80). The firmware
# is built by a make of its own (MAKE, default make) with only the variables
# given here: the calling make's flags and variables are not passed on.
# exit: 0 the identified firmware is built; 3 the fit (or its table) was
# refused, the reason printed: calibrate with the nominal table; else an error.

set -u
toml=$1 plant=$2 seed=$3 out=$4 tables=$5
shift 5
weight=${WEIGHT_G:-80}
name=$(basename "$toml" .toml)_id
id_toml=$out/$name.toml
say() { echo "make sim: $*"; }
# true when $1 is missing or older than any of the other files
stale() {
	t=$1
	shift
	[ -e "$t" ] || return 0
	for d in "$@"; do
		[ "$d" -nt "$t" ] && return 0
	done
	return 1
}
mkdir -p "$out" "$tables" || exit 1
py_src=$(ls host_tools/hallhome/*.py)

case " $* " in
*" --survey-weight-all "*) where="on every tendon in turn" ;;
*) where="per segment" ;;
esac
say "[1/5] survey: the board's \`survey\`, each tendon pulled alone from slack, encoder and" \
	"field streamed; one ${weight} g weight $where (hung by the bench)"
if stale "$out/survey.json" "$BENCH" "$plant" "$FW_ELF"; then
	"$BENCH" "$FW_ELF" --plant "$plant" --seed "$seed" "$@" --survey "$out/bench-survey.json" \
		--survey-weight "$weight" 2>"$out/survey.log" || {
		cat "$out/survey.log"
		say "survey failed"
		exit 1
	}
	"$BENCH" "$FW_ELF" --plant "$plant" --seed "$seed" "$@" --timestamps --limit 180s \
		--at "1s send survey" --until "^<done mode=survey|^<fault" \
		>"$out/board-survey.txt" 2>>"$out/survey.log"
	if "$PY" -m hallhome.op_survey "$out/board-survey.txt" "$out/bench-survey.json" \
		"$out/survey.json.tmp"; then
		mv "$out/survey.json.tmp" "$out/survey.json"
	else
		say "      the board's survey did not complete ($out/board-survey.txt):" \
			"the bench's stepped pulls stand in"
		cp "$out/bench-survey.json" "$out/survey.json"
	fi
	say "      wrote $out/survey.json"
else
	say "      $out/survey.json (kept: this robot was surveyed before)"
fi

say "[2/5] identify: hallhome identify fit $toml $out/survey.json"
if stale "$out/fit.status" "$out/survey.json" "$toml" $py_src; then
	rm -f "$id_toml" "$out/fit.status"
	# the fit's own output streams as it goes; its exit status is kept
	{
		"$PY" -m hallhome identify fit "$toml" "$out/survey.json" --out "$id_toml" \
			--plots "$out/plots" 2>&1
		echo $? >"$out/fit.status"
	} | tee "$out/fit.txt"
else
	say "      (kept from an earlier run of this robot: $out/fit.txt)"
	cat "$out/fit.txt"
fi
if [ "$(cat "$out/fit.status" 2>/dev/null)" != 0 ] || [ ! -f "$id_toml" ]; then
	say "identification refused (reason above): calibrating with the nominal table"
	exit 3
fi

say "[3/5] table: hallhome tables $id_toml"
if stale "$out/tables/$name.c" "$id_toml" $py_src; then
	"$PY" -m hallhome tables --quiet --out-dir "$out/tables" "$id_toml" || {
		rm -f "$out/tables/$name.c"
		say "the table generator refused the identified robot (reason above):" \
			"calibrating with the nominal table"
		exit 3
	}
fi
say "      $out/tables/$name.c"
for f in "$name.c" "$name.json"; do
	cmp -s "$out/tables/$f" "$tables/$f" || cp "$out/tables/$f" "$tables/$f" || exit 1
done

say "[4/5] firmware: make firmware ROBOT=$name (build/fw/$name)"
MAKEFLAGS= MFLAGS= ${MAKE:-make} --no-print-directory firmware ROBOT="$name" ROBOTS_DIR="$out" \
	TABLES_DIR="$tables" || exit 1
exit 0
