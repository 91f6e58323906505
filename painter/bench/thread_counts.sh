# Sourced by tree_vs_openvdb.sh and many_cores.sh: `thread_counts "LIST"`
# fills the array `threads` with the counts of LIST, ascending, each once,
# from 1 (one thread is every table's baseline), or exits with status 2 on
# anything that is not a thread count.
thread_counts() {
    local t
    read -r -a threads <<< "$1"
    for t in "${threads[@]}"; do
        [[ "$t" =~ ^[1-9][0-9]*$ ]] || { echo "THREADS: '$t' is not a thread count" >&2; exit 2; }
    done
    mapfile -t threads < <(printf '%s\n' 1 "${threads[@]}" | sort -nu)
}
