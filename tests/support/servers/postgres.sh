#!/usr/bin/env bash
# A PostgreSQL server in a folder of its own, for the tests (docs/qc.md): initdb and pg_ctl from
# Debian's postgresql as the postgres user, on a free port of 127.0.0.1, with a role `strut` whose
# password (scram-sha-256) is the second argument and a database `qc` it owns.
#   postgres.sh start DIR PASSWORD   # prints PORT=...; exit 2 when it cannot run here
#   postgres.sh restart DIR          # starts the stopped server of DIR again (same port)
#   postgres.sh stop DIR [fast|immediate]   # by the postmaster's process id (DIR/data/postmaster.pid)
set -euo pipefail
cmd=$1
dir=$(realpath -m "$2")
bin=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
run_as_postgres() { su postgres -s /bin/sh -c "$1"; }
if [ "$cmd" = stop ]; then
  signal=INT  # fast shutdown; immediate: QUIT, the way a crash leaves it
  [ "${3:-fast}" = immediate ] && signal=QUIT
  if [ -f "$dir/data/postmaster.pid" ]; then
    pid=$(head -1 "$dir/data/postmaster.pid")
    kill -"$signal" "$pid" 2>/dev/null || true
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || exit 0; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  fi
  exit 0
fi
if [ "$cmd" = restart ]; then
  run_as_postgres "$bin/pg_ctl -D '$dir/data' -l '$dir/log' -w -t 30 start" >/dev/null
  exit 0
fi
[ "$(id -u)" -eq 0 ] || { echo "postgres: needs root (to run initdb as the postgres user)"; exit 2; }
[ -n "$bin" ] && [ -x "$bin/initdb" ] || { echo "postgres: initdb not installed (Debian's postgresql)"; exit 2; }
id postgres >/dev/null 2>&1 || { echo "postgres: no postgres user"; exit 2; }
password=$3
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
mkdir -p "$dir"
# The postgres user walks to its folder through the test's temporary one.
d=$dir; while [ "$d" != / ]; do chmod o+x "$d" 2>/dev/null || true; d=$(dirname "$d"); done
mkdir -p "$dir/data" "$dir/socket"
chown postgres: "$dir/data" "$dir/socket"
touch "$dir/log" && chown postgres: "$dir/log"
run_as_postgres "$bin/initdb -D '$dir/data' -A trust -U postgres" >/dev/null
cat >> "$dir/data/postgresql.conf" <<CONF
port = $port
listen_addresses = '127.0.0.1'
unix_socket_directories = '$dir/socket'
fsync = on
CONF
cat > "$dir/data/pg_hba.conf" <<HBA
local all postgres trust
host all all 127.0.0.1/32 scram-sha-256
HBA
run_as_postgres "$bin/pg_ctl -D '$dir/data' -l '$dir/log' -w -t 30 start" >/dev/null
run_as_postgres "$bin/psql -h '$dir/socket' -p $port -U postgres -q -c \"CREATE ROLE strut LOGIN PASSWORD '$password'\" -c 'CREATE DATABASE qc OWNER strut'" >/dev/null
echo "PORT=$port"
