#!/usr/bin/env python3
"""The tables of docs/RESULTS.md's "ant-linclass diagnosed" section from the diagnosis.json
files `smile linclass-diagnose` writes (standard library only).

    python3 docs/scripts/linclass-diagnosis-table.py docs/results/ant-linclass-diagnosis/rapier/diagnosis.json [more.json ...]
"""
import json
import sys


def f(x):
    return "-" if x is None or x != x else f"{x:.3f}"


def main(paths):
    docs = [json.load(open(p)) for p in paths]
    d0 = docs[0]
    print("bound (eval pairs; fresh pairs):")
    for b in d0["bound"]:
        e, r = b["eval_pairs"], b["fresh_pairs"]
        print(f"| {b['context_size']} | Bayes {f(e['bayes'])} ({f(r['bayes'])}) | SVM {f(e['svm'])} ({f(r['svm'])}) "
              f"| centroid {f(e['centroid'])} ({f(r['centroid'])}) |")
    print("\nvisibility (test demos): step, x on the correct side, clearly, side from the action")
    for v in d0["visibility_test"]:
        if v["time_step"] <= 10:
            print(f"  {v['time_step']}: {f(v['x_on_correct_side'])} {f(v['x_clearly_correct'])} {f(v.get('action_side_accuracy'))} gap {f(v.get('action_gap'))}")
    print(f"  clearly, all kept transitions: test {f(d0['clear_fraction_test'])}, train {f(d0.get('clear_fraction_train'))}")
    print("\nprobe rows:")
    for d in docs:
        for p in d["policies"]:
            test = " / ".join(f(r["pair_accuracy"]) for r in p["probe_test"])
            train = " / ".join(f(r["pair_accuracy"]) for r in (p["probe_train"] or []))
            r2 = f"{f(p['probe_test'][-1]['mean_r2'])} / {f((p['probe_train'] or [{}])[-1].get('mean_r2'))}"
            own = next((t for t in (p["timing"] or []) if t["context_size"] is None), None)
            print(f"| {p['label']} | {test} | {train} | {r2} | {f(own['decided_accuracy']) if own else '-'} |")
    print("\ntiming rows (all sizes; test then train):")
    for d in docs:
        for p in d["policies"]:
            if not p["timing"]:
                continue
            t = next(t for t in p["timing"] if t["context_size"] is None)
            tr = next((t for t in (p.get("timing_train") or []) if t["context_size"] is None), None)
            train = f"{f(tr['decided_accuracy'])} ({f(tr['balanced_decided_accuracy'])})" if tr else "-"
            print(f"| {p['label']} | {t['median_commit_step']:.0f} | {f(t['committed_right'])} / {f(t['committed_wrong'])} / "
                  f"{f(t['never_committed'])} | {f(t['commit_accuracy'])} ({f(t['balanced_commit_accuracy'])}) | "
                  f"{f(t['commits_to_first_target'])} | {f(t['wrong_from_start'])} | {f(t['drifted'])} | {f(t['recovered'])} | "
                  f"{f(t['decided_accuracy'])} ({f(t['balanced_decided_accuracy'])}) | {train} |")
    print("\ndecided accuracy by context size (test):")
    for d in docs:
        for p in d["policies"]:
            if p["timing"]:
                rows = [t for t in p["timing"] if t["context_size"] is not None]
                print(f"  {p['label']}: " + " / ".join(f(t["decided_accuracy"]) for t in rows))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
