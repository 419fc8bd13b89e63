#!/usr/bin/env python3
"""Static worst-case stack bound of the firmware ELF (Cortex-M4F, thumbv7em-none-eabihf).

Usage: scripts/stack-check.py ELF [--max-frame 4096] [--min-headroom 8192] [--json]
         [--indirect CALLER=CALLEE]... [--allow-cycle SUBSTR]... [--priority HANDLER=N]...
Exit 0 ok, 1 a check failed, 2 usage or tool error.  Python 3 stdlib and llvm-objdump
($LLVM_OBJDUMP, else `rustc --print sysroot`/lib/rustlib/*/bin, else PATH).

Method
- Functions: FUNC symbols of `llvm-objdump -t -C` (legacy `$LT$..` escapes decoded, hash
  dropped, `@address` added to a shared name); code: `llvm-objdump -d --no-show-raw-insn`
  cut to [symbol, symbol + size).
- Frame: sp decrements push/stmdb sp! (4 B a register), vpush/vstmdb (8 B a d, 4 B an s
  register), str rX, [sp, #-N]!, sub/sub.w/subw sp by #N or by a register set by movw
  (+movt)/mov #N.  Reported: "prologue" (sum up to the first branch, add sp or pop) and
  "largest" (largest single decrement).  Charged: the sum of ALL decrements (>= prologue;
  LLVM shrink-wraps some prologues behind an early-exit branch).  sp lowered by an unknown
  register (dynamic allocation) fails.
- Calls: bl, blx #imm, b/b<cc>/b.w to another function's first address (tail call, charged
  as a call: slightly pessimistic).  Indirect: blx rN, bx rN (not lr), ldr/mov pc, ldm with
  pc (pop {..,pc}, ldm sp!, ldr pc, [sp], #4 are returns).  A blx rN that a backward scan
  finds set only by movw/movt (maybe via mov/mov<cc>) to function addresses calls those
  (heuristic: the scan ignores join points).
- Depth(f) = frame(f) + deepest callee.  A cycle (strongly connected component) fails unless
  a member's name contains an --allow-cycle substring (default core::fmt); an allowed cycle
  costs twice the sum of its frames (entered and re-entered once: one nested format, or a
  panic in the panic handler, whose re-entry guard then spins).  Deeper recursion: unbounded.
- Indirect rules CALLER=CALLEE (name substrings): a function whose name contains CALLER and
  that has indirect calls left gets edges to every function whose name contains CALLEE, and
  its indirect calls count as covered.  Built in (--indirect adds):
    Executor::run, SyncExecutor::poll -> embassy_executor::raw::TaskStorage<, poll_exited
      (the executor polls each task through a function pointer)
    TaskStorage<, embassy_stm32::, embassy_time, embassy_sync::, USART1/2/6, TIM7, TIM8_BRK_TIM12,
    every task body (_task_inner_function) ->
      embassy_executor::raw::waker::  (RawWakerVTable clone/wake/drop; the executor's is the
      only waker vtable in .rodata; USART2 and TIM8_BRK_TIM12 inline embassy-stm32 code)
    core::fmt -> >::fmt, core::fmt::Write  (fmt::write and Formatter call fmt impls and
      write_str/write_char through vtables; the fmt functions become one allowed cycle)
    _defmt_ -> defmt_rtt::channel::Channel::  (RTT writers; normally resolved by the scan)
  Calls still left are printed per root: the bound does NOT cover them.
- Roots: .vector_table word 1 (reset) is thread mode; every other entry with bit 0 set, not
  DefaultHandler, is a handler (each address once), whose entry costs 104 B (FPU extended
  frame, 26 words) + 4 B alignment.  Priorities are not in the ELF: --priority HANDLER=N
  (0..15, 0 most urgent), defaults TIM7=0, DMA1_STREAM5=2, DMA1_STREAM6=2, DMA2_STREAM0=2,
  DMA2_STREAM1/2/6/7=2, USART1/2/6=3, TIM8_BRK_TIM12=3; a handler without one is a level of its own.
  Same-level handlers do not nest: worst case = thread depth + per level (deepest handler +
  108) + HardFault (+ NMI unless DefaultHandler), which can come on top of everything.
- Stack: flip-link (_stack_start at or below the RAM sections): [_stack_end if below
  _stack_start, else --ram-origin 0x20000000, _stack_start).  cortex-m-rt default
  (_stack_start above them): [max(end of .data/.bss/.uninit, _stack_end), _stack_start).

Limits: a static bound from machine code.  Indirect calls are covered only as far as the
rules say; priorities are assumptions.  Rust emits no dynamic stack allocation (no alloca;
a `sub sp, rX` is reported) and does not use the stack probe `__rust_probestack` on
thumbv7em (a function of that name is reported).  Code outside FUNC symbols, inline asm
that moves sp and code run from RAM are not analysed.
"""
import argparse, bisect, glob, json, os, re, shutil, struct, subprocess, sys

EXC_FRAME, CYCLE_PASSES = 104 + 4, 2
DEFAULT_PRIO = {"TIM7": 0, "DMA1_STREAM5": 2, "DMA1_STREAM6": 2, "DMA2_STREAM0": 2, "DMA2_STREAM1": 2,
                "DMA2_STREAM2": 2, "DMA2_STREAM6": 2, "DMA2_STREAM7": 2, "USART6": 3,
                "USART2": 3, "USART1": 3, "TIM8_BRK_TIM12": 3}
DEFAULT_RULES = [(c, t) for c in ("Executor::run", "SyncExecutor::poll")
                 for t in ("embassy_executor::raw::TaskStorage<", "embassy_executor::raw::poll_exited")]
DEFAULT_RULES += [(c, "embassy_executor::raw::waker::") for c in (
    "embassy_executor::raw::TaskStorage<", "embassy_stm32::", "embassy_time", "embassy_sync::",
    "USART2", "USART1", "USART6", "TIM8_BRK_TIM12", "TIM7",
    # every #[embassy_executor::task] body (the macro's `__<name>_task_inner_function`):
    # waker registration inlined into a task calls the same vtable
    "_task_inner_function")]
DEFAULT_RULES += [("core::fmt", ">::fmt"), ("core::fmt", "core::fmt::Write"),
                  ("_defmt_", "defmt_rtt::channel::Channel::")]
DEFAULT_ALLOW = ["core::fmt"]
EXC_NAMES = {2: "NMI", 3: "HardFault", 4: "MemManage", 5: "BusFault", 6: "UsageFault",
             11: "SVCall", 12: "DebugMonitor", 14: "PendSV", 15: "SysTick"}
COND = r"(?:eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)"
BRANCH = re.compile(r"^(b|bl|blx|bx|cbz|cbnz|tbb|tbh)(%s)?(\.w|\.n)?$" % COND)
ALIAS = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}


class ToolError(Exception):
    """A tool, file or ELF problem: exit code 2."""


def find_objdump():
    if os.environ.get("LLVM_OBJDUMP"):
        return os.environ["LLVM_OBJDUMP"]
    try:
        root = subprocess.run(["rustc", "--print", "sysroot"], capture_output=True, text=True,
                              check=True).stdout.strip()
        hits = sorted(glob.glob(os.path.join(root, "lib/rustlib/*/bin/llvm-objdump")),
                      key=lambda p: "x86_64-unknown-linux-gnu" not in p)
        if hits:
            return hits[0]
    except (OSError, subprocess.CalledProcessError):
        pass
    if not shutil.which("llvm-objdump"):
        raise ToolError("llvm-objdump not found (rustup component add llvm-tools, or set LLVM_OBJDUMP)")
    return shutil.which("llvm-objdump")


def objdump(tool, *args):
    r = subprocess.run([tool, *args], capture_output=True, text=True)
    if r.returncode:
        raise ToolError("llvm-objdump %s: %s" % (" ".join(args), r.stderr.strip()))
    return r.stdout


def read_sections(path):
    """Sections of a 32-bit little-endian ARM ELF: {name: (addr, size, flags, bytes)}."""
    d = open(path, "rb").read()
    if d[:6] != b"\x7fELF\x01\x01" or struct.unpack_from("<H", d, 18)[0] != 40:
        raise ToolError("%s: not a 32-bit little-endian ARM ELF" % path)
    shoff, = struct.unpack_from("<I", d, 0x20)
    size, num, strndx = struct.unpack_from("<HHH", d, 0x2E)
    hdrs = [struct.unpack_from("<10I", d, shoff + i * size) for i in range(num)]
    strs = hdrs[strndx][4]
    return {d[strs + h[0]:d.index(b"\0", strs + h[0])].decode():
            (h[3], h[5], h[2], d[h[4]:h[4] + h[5]] if h[1] != 8 else b"") for h in hdrs}


def clean(name):
    name = re.sub(r"::h[0-9a-f]{16}$", "", re.sub(r"^\.(hidden|protected|internal) ", "", name))
    name = re.sub(r"(^|::|<)_\$", r"\1$", name).replace("..", "::")
    esc = {"LT": "<", "GT": ">", "C": ",", "RF": "&", "BP": "*", "SP": "@", "LP": "(", "RP": ")"}
    return re.sub(r"\$(LT|GT|C|RF|BP|SP|LP|RP|u[0-9a-f]{2})\$",
                  lambda m: esc.get(m.group(1)) or chr(int(m.group(1)[1:], 16)), name)


def reg(tok):
    tok = ALIAS.get(tok.strip(), tok.strip())
    return tok if re.match(r"^(r\d+|lr)$", tok) else None


def reglist(text):
    """Registers of a list such as {r4-r7, lr} or {d8-d15}."""
    out = []
    for part in text[text.find("{"):].strip("{} ").split(","):
        m = re.match(r"\s*([a-z]+)(\d+)\s*-\s*[a-z]+(\d+)", part)
        out += ["%s%d" % (m.group(1), i) for i in range(int(m.group(2)), int(m.group(3)) + 1)] \
            if m else [ALIAS.get(part.strip(), part.strip())]
    return out


def writes(base, ops):
    """Core registers an instruction writes (rough: enough for the backward constant scan)."""
    m = re.search(r"\[(\w+)(?:, [^\]]*)?\](!|, #)", ops) or re.match(r"(\w+)!", ops)
    w = {ALIAS.get(m.group(1), m.group(1))} if m else set()
    if base.startswith(("pop", "ldm")):
        return w | set(reglist(ops))
    if re.match(r"(cmp|cmn|tst|teq|it|b|push|vpush|stm|vst|pld|dmb|dsb|isb|nop|msr|cps|wf|sev|udf|bkpt|svc)",
                base) or (base.startswith("str") and not base.startswith("strex")):
        return w
    n = 2 if re.match(r"(ldrd|ldrexd|umull|smull|umlal|smlal|vmov)", base) else 1
    for tok in ops.split("[")[0].split(",")[:n]:
        if not reg(tok):
            break
        w.add(reg(tok))
    return w


def resolve(body, i, r0, funcs):
    """Functions that register r0 can hold at body[i] when only movw/movt/mov set it, else None."""
    tracked, hi, found = {r0}, {}, set()
    for _, mn, ops in reversed(body[:i]):
        m = re.match(r"^(mov[wt]?)(%s)?(\.w)?$" % COND, mn)
        imm = re.match(r"\w+, #(0x[0-9a-f]+|\d+)$", ops)
        src = re.match(r"\w+, (r\d+|ip|sb|sl|fp)$", ops)
        for r in writes(re.sub(r"\.[wn]$", "", mn), ops) & tracked:
            if m and m.group(1) == "movt" and imm:
                hi[r] = int(imm.group(1), 0)
            elif m and imm and r in hi:
                found.add(hi.pop(r) << 16 | int(imm.group(1), 0))
            elif m and m.group(1) == "mov" and src:
                tracked.add(reg(src.group(1)))
            else:
                return None
            if not m.group(2) and m.group(1) != "movt":
                tracked.discard(r)
        if not tracked:
            break
    if tracked or not found or any(a & 1 == 0 or a - 1 not in funcs for a in found):
        return None
    return {a - 1 for a in found}


def is_indirect(br, base, ops):
    """A call or jump through a register or memory (returns excluded)."""
    if br:
        return br.group(1) in ("blx", "bx") and ops != "lr" and not ops.startswith("0x")
    if base.startswith("pop") or (base.startswith("ldm") and ops.startswith("sp!")) or \
            (base.startswith("ldr") and ops.startswith("pc, [sp], #")):
        return False
    return (base.startswith(("ldr", "mov")) and ops.startswith("pc,")) or \
        (base.startswith("ldm") and re.search(r"\bpc\}", ops) is not None)


def scan(f, funcs, starts):
    """Frame sizes, direct calls and indirect call sites of one function."""
    f.update(prologue=0, frame=0, largest=0, dynamic=False, calls={}, indirect=[])
    consts, in_prologue = {}, True
    for i, (a, mn, ops) in enumerate(f["body"]):
        base, dec = re.sub(r"\.[wn]$", "", mn), 0
        if base in ("push", "vpush") or (base in ("stmdb", "stmfd", "vstmdb") and ops.startswith("sp!")):
            dec = sum(8 if r.startswith("d") else 4 for r in reglist(ops))
        elif re.match(r"^subw?s?$", base) and re.match(r"sp, (sp, )?", ops):
            arg = re.sub(r"^sp, (sp, )?", "", ops)
            if arg.startswith("#"):
                dec = int(arg[1:], 0)
            elif reg(arg) in consts:
                dec = consts[reg(arg)]
            else:
                f["dynamic"] = True
        elif base.startswith("str") and re.search(r"\[sp, #-(\w+)\]!$", ops):
            dec = int(re.search(r"\[sp, #-(\w+)\]!$", ops).group(1), 0)
        m = re.match(r"^(\w+), #(0x[0-9a-f]+|\d+)$", ops)
        if m and reg(m.group(1)) and base in ("movw", "mov", "movs"):
            consts[reg(m.group(1))] = int(m.group(2), 0)
        elif m and reg(m.group(1)) and base == "movt":
            consts[reg(m.group(1))] = consts.get(reg(m.group(1)), 0) & 0xFFFF | int(m.group(2), 0) << 16
        br = BRANCH.match(mn)
        if br or base.startswith(("pop", "vpop", "ldm")) or "[sp], #" in ops or \
                (re.match(r"^addw?s?$", base) and ops.startswith("sp,")):
            in_prologue = False
        f["prologue"] += dec if in_prologue else 0
        f["frame"] += dec
        f["largest"] = max(f["largest"], dec)
        tgt = int(ops.split()[0], 16) if re.match(r"^0x[0-9a-f]+", ops) else None
        if br and br.group(1) in ("bl", "blx") and tgt is not None:
            k = bisect.bisect_right(starts, tgt) - 1
            if k >= 0:
                f["calls"].setdefault(starts[k], "call")
        elif br and br.group(1) == "b" and tgt in funcs and not f["addr"] <= tgt < f["end"]:
            f["calls"].setdefault(tgt, "tail")
        elif is_indirect(br, base, ops):
            targets = resolve(f["body"], i, reg(ops), funcs) if br and reg(ops) else None
            for t in targets or ():
                f["calls"].setdefault(t, "const")
            if not targets:
                f["indirect"].append("%#x: %s %s" % (a, mn, ops))


def analyse(elf, tool, rules):
    syms, funcs = {}, {}
    for line in objdump(tool, "-t", "-C", elf).splitlines():
        m = re.match(r"^([0-9a-f]{8}) (.{7}) (\S+)\s+([0-9a-f]+) (.+)$", line)
        if m:
            addr, flags, name = int(m.group(1), 16), m.group(2), clean(m.group(5))
            syms.setdefault(name, addr)
            if "F" in flags:
                f = funcs.setdefault(addr, {"addr": addr, "size": 0, "aliases": set(), "body": []})
                f["size"] = max(f["size"], int(m.group(4), 16))
                f["aliases"].add((flags[0] == "l", name))
    if not funcs:
        raise ToolError("no FUNC symbols in %s" % elf)
    starts = sorted(funcs)
    for i, a in enumerate(starts):
        f = funcs[a]
        f["end"] = a + f["size"] if f["size"] else (starts[i + 1] if i + 1 < len(starts) else a + 2)
        f["aliases"] = [n for _, n in sorted(f["aliases"], key=lambda x: (x[0], len(x[1]), x[1]))]
    first = [f["aliases"][0] for f in funcs.values()]
    for f in funcs.values():
        f["name"] = f["aliases"][0] + ("@%#x" % f["addr"] if first.count(f["aliases"][0]) > 1 else "")
    for line in objdump(tool, "-d", "--no-show-raw-insn", elf).splitlines():
        m = re.match(r"^\s*([0-9a-f]+):\s+(?:(?:[0-9a-f]{2} )+\s*)?(\S+)\s*(.*?)(?:\s+@ .*)?$", line)
        if m and not m.group(2).startswith("."):
            a = int(m.group(1), 16)
            k = bisect.bisect_right(starts, a) - 1
            if k >= 0 and a < funcs[starts[k]]["end"]:
                funcs[starts[k]]["body"].append((a, m.group(2), m.group(3)))
    for f in funcs.values():
        scan(f, funcs, starts)
    for f in funcs.values():  # indirect rules
        hit = [callee for caller, callee in rules if f["indirect"] and any(caller in n for n in f["aliases"])]
        f["covered"] = bool(hit)
        for g in funcs.values():
            if any(c in n for c in hit for n in g["aliases"]):
                f["calls"].setdefault(g["addr"], "indirect rule")
    return syms, funcs


def sccs(funcs):
    """Tarjan's strongly connected components, callees first."""
    index, low, stack, out = {}, {}, [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in funcs[v]["calls"]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            out.append(stack[stack.index(v):])
            del stack[stack.index(v):]
    sys.setrecursionlimit(max(10000, 4 * len(funcs)))
    for v in funcs:
        if v not in index:
            visit(v)
    return out


def depths(funcs, allow):
    comp, info, cycles = {}, {}, []
    for members in sccs(funcs):
        cid = min(members)
        comp.update((v, cid) for v in members)
        cyclic = len(members) > 1 or members[0] in funcs[members[0]]["calls"]
        if cyclic:
            cycles.append({"functions": sorted(funcs[v]["name"] for v in members),
                           "allowed": any(s in n for s in allow for v in members for n in funcs[v]["aliases"])})
        callee = max(((info[comp[w]]["depth"], w) for v in members for w in funcs[v]["calls"]
                      if comp.get(w) != cid), default=(0, None))
        own = sum(funcs[v]["frame"] for v in members) * (CYCLE_PASSES if cyclic else 1)
        info[cid] = {"depth": own + callee[0], "own": own, "next": callee[1], "cyclic": cyclic,
                     "members": sorted(members, key=lambda v: (-funcs[v]["frame"], funcs[v]["name"]))}
    return comp, info, cycles


def path_of(v, comp, info, funcs):
    path, via = [], "root"
    while v is not None:
        c = info[comp[v]]
        name = funcs[v]["name"] if not c["cyclic"] else "cycle x%d of %s" % (
            CYCLE_PASSES, ", ".join("%s %d" % (funcs[m]["name"], funcs[m]["frame"]) for m in c["members"]))
        path.append({"function": name, "frame": c["own"], "via": via})
        via = next((funcs[m]["calls"][c["next"]] for m in c["members"] if c["next"] in funcs[m]["calls"]), None)
        v = c["next"]
    return path


def stack_region(sections, syms, ram_origin):
    top, end = syms.get("_stack_start"), syms.get("_stack_end")
    ram = [(a, a + s) for a, s, fl, _ in sections.values() if fl & 3 == 3 and s and a >= ram_origin]
    if top is None or not ram:
        raise ToolError("no _stack_start symbol or no RAM sections")
    lo, hi = min(a for a, _ in ram), max(e for _, e in ram)
    if top <= lo:
        return "flip-link (stack at the bottom of RAM, below .data/.bss)", \
            end if end is not None and end < top else ram_origin, top
    if top >= hi:
        return "cortex-m-rt default, no flip-link (stack at the top of RAM, grows down into .bss)", \
            max(hi, end if end is not None and end <= top else hi), top
    raise ToolError("_stack_start %#x lies inside the RAM sections [%#x, %#x)" % (top, lo, hi))


def main():
    ap = argparse.ArgumentParser(description="Static worst-case stack bound of a Cortex-M ELF.")
    ap.add_argument("elf")
    ap.add_argument("--max-frame", type=int, default=4096)
    ap.add_argument("--min-headroom", type=int, default=8192)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--indirect", action="append", default=[], metavar="CALLER=CALLEE")
    ap.add_argument("--allow-cycle", action="append", default=[], metavar="SUBSTR")
    ap.add_argument("--priority", action="append", default=[], metavar="HANDLER=N")
    ap.add_argument("--ram-origin", type=lambda s: int(s, 0), default=0x20000000)
    ap.add_argument("--forbid-symbol", action="append", default=[], metavar="SUBSTR",
                    help="fail if any function's name contains SUBSTR (e.g. a logger's blocking write)")
    ap.add_argument("--brief", action="store_true",
                    help="text report without the per-root call paths")
    ap.add_argument("--allow-unresolved", action="store_true",
                    help="do not fail on indirect calls no rule covers")
    a = ap.parse_args()
    rules, prio = list(DEFAULT_RULES), dict(DEFAULT_PRIO)
    for kind, spec in [("indirect", s) for s in a.indirect] + [("priority", s) for s in a.priority]:
        k, _, v = spec.partition("=")
        if not k or not v or (kind == "priority" and not (v.isdigit() and int(v) <= 15)):
            ap.error("bad --%s %r" % (kind, spec))
        if kind == "indirect":
            rules.append((k, v))
        else:
            prio[k] = int(v)
    try:
        tool = find_objdump()
        sections = read_sections(a.elf)
        syms, funcs = analyse(a.elf, tool, rules)
        layout, bottom, top = stack_region(sections, syms, a.ram_origin)
        vt = sections.get(".vector_table", (0, 0, 0, b""))[3]
        if len(vt) < 8 or struct.unpack_from("<I", vt, 4)[0] & ~1 not in funcs:
            raise ToolError("no .vector_table section with a reset vector")
    except (ToolError, OSError) as e:
        print("stack-check: error: %s" % e, file=sys.stderr)
        return 2
    comp, info, cycles = depths(funcs, DEFAULT_ALLOW + a.allow_cycle)
    default = {syms.get(n) for n in ("DefaultHandler", "DefaultHandler_")}
    roots, seen, levels = [], set(), {}
    for slot, w in enumerate(struct.unpack_from("<%dI" % (len(vt) // 4), vt)[1:], 1):
        addr = w & ~1
        if not w & 1 or addr in default or addr in seen or addr not in funcs:
            continue
        seen.add(addr)
        f, caps = funcs[addr], [n for n in funcs[addr]["aliases"] if re.match(r"^[A-Z][A-Z0-9_]*$", n)]
        name = EXC_NAMES.get(slot) if 2 <= slot < 16 else (caps or [f["name"]])[0]
        p = "thread" if slot == 1 else "fixed %d" % (slot - 4) if slot in (2, 3) else \
            next((prio[n] for n in [name] + f["aliases"] if n in prio), None)
        level = p if p is not None else "own " + name
        reach, todo = {addr}, [addr]
        while todo:
            for t in funcs[todo.pop()]["calls"]:
                if t not in reach:
                    reach.add(t); todo.append(t)
        r = {"root": name, "function": f["name"], "priority": p, "depth_bytes": info[comp[addr]]["depth"],
             "exception_frame_bytes": 0 if slot == 1 else EXC_FRAME, "path": path_of(addr, comp, info, funcs),
             "unresolved_indirect": sorted("%s: %s" % (funcs[v]["name"], c) for v in reach
                                           if not funcs[v]["covered"] for c in funcs[v]["indirect"])}
        roots.append(r)
        cost = r["depth_bytes"] + r["exception_frame_bytes"]
        if level not in levels or cost > levels[level][0]:
            levels[level] = (cost, name)
    order = sorted(levels, key=lambda k: (k != "thread", isinstance(k, str) and k.startswith("fixed"),
                                          -k if isinstance(k, int) else 0, str(k)))
    worst, stack = sum(c for c, _ in levels.values()), top - bottom
    frames = sorted(funcs.values(), key=lambda f: -f["frame"])
    big = [f for f in frames if f["frame"] > a.max_frame]
    dyn = [f["name"] for f in frames if f["dynamic"]]
    probe = [f["name"] for f in frames if "probestack" in f["name"]]
    unresolved = sorted({u for r in roots for u in r["unresolved_indirect"]})
    forbidden = sorted({f["name"] for f in funcs.values() for sub in a.forbid_symbol if sub in f["name"]})
    fail = bool(big or dyn or any(not c["allowed"] for c in cycles) or stack - worst < a.min_headroom
                or forbidden or (unresolved and not a.allow_unresolved))
    if a.json:
        print(json.dumps({
            "stack_bytes": stack, "worst_case_bytes": worst, "headroom_bytes": stack - worst,
            "layout": layout, "stack_region": [hex(bottom), hex(top)], "ok": not fail,
            "largest_frames": [{"function": f["name"], "bytes": f["frame"], "prologue_bytes": f["prologue"],
                                "largest_single_bytes": f["largest"]} for f in frames[:10]],
            "over_max_frame": [{"function": f["name"], "bytes": f["frame"]} for f in big],
            "roots": roots, "levels": [{"level": k, "root": levels[k][1], "bytes": levels[k][0]} for k in order],
            "unresolved_indirect": unresolved, "cycles": cycles, "dynamic_sp": dyn, "probestack": probe,
            "forbidden": forbidden},
            indent=1))
        return 1 if fail else 0
    print("stack-check %s\nlayout: %s\nstack: [%#010x, %#010x) = %d bytes" % (a.elf, layout, bottom, top, stack))
    print("\nlargest frames (bytes = all sp decrements; prologue sum, largest single decrement):")
    for f in frames[:10]:
        print("  %7d  %s  (prologue %d, largest %#x)" % (f["frame"], f["name"], f["prologue"], f["largest"]))
    for f in big:
        print("FAIL frame %d > --max-frame %d: %s" % (f["frame"], a.max_frame, f["name"]))
    print("".join("FAIL sp lowered by an unknown register (dynamic stack): %s\n" % n for n in dyn) +
          "".join("note: stack probe present: %s\n" % n for n in probe), end="")
    for c in cycles:
        print("%s cycle: %s" % ("allowed" if c["allowed"] else "FAIL", ", ".join(c["functions"])))
    for r in roots:
        print("\nroot %s (%s), priority %s: depth %d%s" % (r["root"], r["function"], r["priority"], r["depth_bytes"],
              " + exception frame %d" % r["exception_frame_bytes"] if r["exception_frame_bytes"] else ""))
        for s in ([] if a.brief else r["path"]):
            via = "" if s["via"] in ("call", "root") else "  [%s]" % s["via"]
            print("  %7d  %s%s" % (s["frame"], s["function"], via))
        for u in r["unresolved_indirect"]:
            print("  NOT COVERED: indirect call in %s" % u)
    print("\nworst case (one root per level; handlers add the %d-byte exception frame):" % EXC_FRAME)
    for k in order:
        print("  %-22s %7d  %s" % (k if isinstance(k, str) else "priority %d" % k, levels[k][0], levels[k][1]))
    print("  %-22s %7d\nheadroom: %d - %d = %d bytes (minimum %d)" % (
        "total", worst, stack, worst, stack - worst, a.min_headroom))
    print("indirect calls not covered by the bound: %d" % len(unresolved))
    if unresolved and not a.allow_unresolved:
        print("FAIL indirect calls no rule covers (add an --indirect rule)")
    for n in forbidden:
        print("FAIL forbidden symbol linked: %s" % n)
    if stack - worst < a.min_headroom:
        print("FAIL headroom %d < --min-headroom %d" % (stack - worst, a.min_headroom))
    print("\nstack-check: %s" % ("FAIL" if fail else "ok"))
    return 1 if fail else 0


if __name__ == "__main__":
    sys.exit(main())
