#!/usr/bin/env bash
# Opens lcm-spy, LCM's traffic inspector, with this project's message types
# (package aglcm: air_keyframe_t, relative_pose_t, camera_info_t, image_t,
# odometry_t, point_cloud_t) on the class path, so it decodes them field by
# field instead of listing bare fingerprints.
#
#   tools/lcm_spy.sh                               # the default LCM network (below)
#   tools/lcm_spy.sh --lcm-url='udpm://239.255.76.67:7667?ttl=1'
#   LCM_DEFAULT_URL='udpm://239.255.76.67:7667?ttl=1' tools/lcm_spy.sh
#   AG_BUILD_DIR=build-debug tools/lcm_spy.sh      # the jar of another build folder
#
# Which LCM network it listens to: `--lcm-url=URL` (or `-l URL`) wins; else the
# LCM_DEFAULT_URL environment variable, as for every LCM program; else LCM's
# default, udpm://239.255.76.67:7667. Use the same URL as air_agent and
# ground_server. With UDP multicast (udpm://group:port?ttl=N), ttl=0 keeps the
# traffic on this machine and ttl=1 reaches the local network (e.g. the radio
# link between UAV and UGV); other providers: tcpq://host:port, file://log.lcm
# (replays an lcm-logger log), memq:// (in-process only).
#
# Needs: java (default-jre), /usr/share/java/lcm.jar (liblcm-java), our jar
# <build>/lcmtypes/ag_lcmtypes.jar (built by the default build when javac and
# jar are installed: default-jdk-headless), and for the field viewer and its
# charts /usr/share/java/jchart2d.jar (libjchart2d-java).
# Environment: AG_BUILD_DIR (default <repo>/build), AG_LCMTYPES_JAR (the jar
# itself, overrides AG_BUILD_DIR), LCM_JAR, JAVA (default: java on PATH).
#
# Why not Debian's /usr/bin/lcm-spy: it passes -Xincgc, an option Java 9 and
# later reject, so it cannot start on Debian 12's Java 17; this script runs the
# same class (lcm.spy.Spy) itself.
set -euo pipefail

repo_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${AG_BUILD_DIR:-${repo_dir}/build}"
types_jar="${AG_LCMTYPES_JAR:-${build_dir}/lcmtypes/ag_lcmtypes.jar}"
java="${JAVA:-java}"

fail() {
  echo "lcm_spy.sh: $*" >&2
  exit 1
}

if [ ! -f "${types_jar}" ]; then
  fail "${types_jar} is not built, so lcm-spy could not decode our messages.
  Build it:  cmake --build ${build_dir} --target ag_lcmtypes_jar
  (CMake builds it only when javac and jar were found at configure time:
  install default-jdk-headless and re-run cmake; or point AG_BUILD_DIR at
  another build folder, or AG_LCMTYPES_JAR at the jar)"
fi

if ! command -v "${java}" >/dev/null 2>&1; then
  fail "no '${java}' on PATH: install a Java runtime (Debian: default-jre)"
fi

lcm_jar="${LCM_JAR:-}"
if [ -z "${lcm_jar}" ]; then
  for candidate in /usr/share/java/lcm.jar /usr/local/share/java/lcm.jar; do
    if [ -f "${candidate}" ]; then
      lcm_jar="${candidate}"
      break
    fi
  done
fi
if [ -z "${lcm_jar}" ] || [ ! -f "${lcm_jar}" ]; then
  fail "LCM's Java library lcm.jar not found (Debian: liblcm-java; or set LCM_JAR)"
fi

class_path="${lcm_jar}"
jchart2d_jar=""
for candidate in /usr/share/java/jchart2d.jar /usr/local/share/java/jchart2d.jar; do
  if [ -f "${candidate}" ]; then
    jchart2d_jar="${candidate}"
    break
  fi
done
if [ -n "${jchart2d_jar}" ]; then
  class_path="${class_path}:${jchart2d_jar}"
else
  # lcm-spy starts and finds our types without it, but its field viewer
  # (lcm.spy.ObjectPanel, opened by double-clicking a channel) is built on
  # jchart2d and fails to load.
  echo "lcm_spy.sh: jchart2d.jar not found (Debian: libjchart2d-java): lcm-spy will start," \
    "but opening a channel's field view will fail" >&2
fi
class_path="${class_path}:${types_jar}"

# preferIPv4Stack: LCM's UDP multicast provider needs IPv4 sockets.
exec "${java}" -Djava.net.preferIPv4Stack=true -Xmx512m -cp "${class_path}" lcm.spy.Spy "$@"
