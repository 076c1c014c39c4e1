"""``cache``: show or empty the cache of compiled model functions."""

from __future__ import annotations

from ._common import add_force, add_json, check_outputs, write_json


def register(sub) -> None:
    p = sub.add_parser("cache", help="show or empty the cache of compiled model functions",
                       description="Compiled model functions are kept on disk between runs, so that a model "
                                   "is compiled once per machine (folder: $CASADICAL_CACHE, else "
                                   "$XDG_CACHE_HOME/casadical or ~/.cache/casadical; size limit "
                                   "$CASADICAL_CACHE_MAX_MB, default 256, least recently used entries go "
                                   "first). --info shows the folder and what it holds, --clear empties it "
                                   "(the next run compiles again).")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--info", action="store_true", help="folder, entries, size, limit and compiler")
    what.add_argument("--clear", action="store_true", help="remove every compiled function of the cache")
    add_json(p, "the cache information (with --info)")
    add_force(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..model import _jitcache as jitcache

    if args.clear:
        n = jitcache.clear()
        print(f"removed {n} file(s) from {jitcache.cache_dir()}")
        return 0
    check_outputs({"--json": args.json}, [], args.force)
    info = jitcache.info()
    if args.json:
        write_json(args.json, info.to_dict(), args.force)
    if args.json != "-":
        print(f"folder:   {info.folder}{'' if info.folder.exists() else ' (not created yet)'}\n"
              f"entries:  {info.entries} compiled function(s), {info.bytes / 1e6:.1f} MB "
              f"(limit {info.max_bytes / 1e6:.0f} MB)\n"
              f"compiler: {info.compiler or 'none found: models run in the CasADi virtual machine'} "
              f"(CasADi {info.casadi_version})")
    return 0
