#!/usr/bin/env python3
"""Static worst-case stack bound of the firmware ELF (Cortex-M4F, thumbv7em-none-eabihf).

Usage: scripts/stack-check.py ELF [--max-frame 4096] [--min-headroom 8192] [--json]
         [--indirect CALLER=CALLEE]... [--allow-cycle SUBSTR]... [--priority HANDLER=N]...
Exit: 0 ok, 1 a check failed, 2 usage or tool error.  Python 3 stdlib + llvm-objdump
(from `rustc --print sysroot`/lib/rustlib/*/bin, else PATH; or $LLVM_OBJDUMP).

Method
- Functions: FUNC symbols of `llvm-objdump -t -C` (Rust legacy `$LT$`.. escapes decoded,
  `::h<hash>` dropped; a name shared by several functions gets `@address`).  Code comes
  from `llvm-objdump -d --no-show-raw-insn`, cut to [symbol, symbol + size).
- Frame: sp decrements push/push.w/stmdb sp! (4 B a register), vpush/vstmdb (8 B a d
  register, 4 B an s register), `str rX, [sp, #-N]!`, sub/sub.w/subw sp by #N or by a
  register set by movw(+movt)/mov #N.  `prologue` = the sum up to the first branch,
  add sp or pop; `largest` = the largest single decrement.  The frame used for the bound
  is the sum of ALL decrements in the function (>= prologue): LLVM shrink-wraps some
  prologues behind an early-exit branch, where the prologue sum would read 0.  An sp
  decrement by an unknown register (dynamic allocation) is a failure.
- Call graph: bl / blx #imm; b / b<cc> / b.w whose target is another function's first
  address (tail call, charged as a call: slightly pessimistic).  Indirect: blx rN,
  bx rN (not lr), ldr pc / mov pc / ldm with pc (pop {..,pc} and ldr pc, [sp], #4 are
  returns).  `blx rN` whose rN is, scanning back, only ever set by movw/movt (possibly via
  mov/mov<cc>) to a function address is resolved to it (heuristic: ignores join points).
- Depth(f) = frame(f) + max depth of callees.  Cycles (strongly connected components)
  fail unless a member's name contains an --allow-cycle substring; an allowed cycle is
  charged the sum of its members' frames (each member active once: no bound on depth of
  real recursion).  Default allow-list: `core::fmt` (see below).
- Indirect rules CALLER=CALLEE (substrings of names): every function whose name contains
  CALLER and that has an indirect call left unresolved gets edges to every function whose
  name contains CALLEE; all its indirect calls then count as covered.  Built-in defaults
  (always on, --indirect adds to them):
    Executor::run, SyncExecutor::poll       -> embassy_executor::raw::TaskStorage<, poll_exited
        (the executor calls each task's poll through a function pointer)
    TaskStorage<, embassy_stm32::, embassy_time, embassy_sync::, USART2, TIM8_BRK_TIM12
                                             -> embassy_executor::raw::waker::
        (RawWakerVTable calls wake/wake_by_ref/drop; the only waker vtable in .rodata is
        the executor's; USART2 and TIM8_BRK_TIM12 (time driver) inline embassy-stm32 code)
    core::fmt                                -> >::fmt, core::fmt::Write
        (fmt::write / Formatter call trait-object fmt and write_str/write_char impls; this
        makes the fmt functions one cycle, allowed by default and charged the sum of its
        frames: a bound for one level of nested formatting)
    _defmt_                                  -> defmt_rtt::channel::Channel::
        (RTT write function pointers, normally already resolved by the movw/movt scan)
  Calls still unresolved are printed per root: the bound does NOT cover them.
- Roots: the reset vector (word 1 of .vector_table) runs thread mode; every other vector
  entry (bit 0 set, not DefaultHandler, each address once) is a handler.  An exception
  entry costs 104 B (FPU extended frame, 26 words) + 4 B alignment.  Priorities are not
  in the ELF: --priority HANDLER=N (0..15, 0 most urgent), defaults TIM7=0,
  DMA1_STREAM5=2, DMA1_STREAM6=2, DMA2_STREAM0=2, USART2=3, USART1=3, TIM8_BRK_TIM12=3;
  a handler without one is its own level.  Same-level handlers do not nest, so
  worst case = thread depth + sum over levels of (deepest handler + 108) + HardFault (+
  NMI if it has its own handler), which sit on top of everything.
- Stack: flip-link layout (_stack_start below the RAM sections): [_stack_end if it lies
  below _stack_start, else --ram-origin (0x20000000), _stack_start).  cortex-m-rt default
  layout (_stack_start at/above the RAM sections): [max(end of .data/.bss/.uninit,
  _stack_end), _stack_start).  Headroom = stack - worst case; fail below --min-headroom.

Limits: a static bound from the machine code only.  Indirect calls are covered only as
far as the rules above say; interrupt priorities are assumptions; an allowed cycle counts
one pass.  Rust emits no dynamic stack allocation (no alloca; a `sub sp, rX` is reported),
and the stack probe `__rust_probestack` is not used on thumbv7em (checked: reported if
called).  Inline asm that moves sp, code outside FUNC symbols and RAM functions are not
analysed.
"""
import argparse, bisect, glob, json, os, re, shutil, struct, subprocess, sys

EXC_FRAME = 104 + 4
DEFAULT_PRIO = {"TIM7": 0, "DMA1_STREAM5": 2, "DMA1_STREAM6": 2, "DMA2_STREAM0": 2,
                "USART2": 3, "USART1": 3, "TIM8_BRK_TIM12": 3}
WAKER = "embassy_executor::raw::waker::"
DEFAULT_RULES = [(c, t) for c in ("Executor::run", "SyncExecutor::poll")
                 for t in ("embassy_executor::raw::TaskStorage<", "embassy_executor::raw::poll_exited")]
DEFAULT_RULES += [(c, WAKER) for c in ("embassy_executor::raw::TaskStorage<", "embassy_stm32::",
                                       "embassy_time", "embassy_sync::", "USART2", "TIM8_BRK_TIM12")]
DEFAULT_RULES += [("core::fmt", ">::fmt"), ("core::fmt", "core::fmt::Write"),
                  ("_defmt_", "defmt_rtt::channel::Channel::")]
DEFAULT_ALLOW = ["core::fmt"]
EXC_NAMES = {2: "NMI", 3: "HardFault", 4: "MemManage", 5: "BusFault", 6: "UsageFault",
             11: "SVCall", 12: "DebugMonitor", 14: "PendSV", 15: "SysTick"}
COND = r"(?:eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)"
BRANCH = re.compile(r"^(b|bl|blx|bx|cbz|cbnz|tbb|tbh)(%s)?(\.w|\.n)?$" % COND)
REGALIAS = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}


class ToolError(Exception):
    pass


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
    tool = shutil.which("llvm-objdump")
    if not tool:
        raise ToolError("llvm-objdump not found (rustup component add llvm-tools, or set LLVM_OBJDUMP)")
    return tool


def objdump(tool, *args):
    r = subprocess.run([tool, *args], capture_output=True, text=True)
    if r.returncode:
        raise ToolError("%s %s failed: %s" % (tool, " ".join(args), r.stderr.strip()))
    return r.stdout


def read_sections(path):
    """Section headers of a 32-bit little-endian ARM ELF: {name: (addr, size, flags, data)}."""
    d = open(path, "rb").read()
    if d[:4] != b"\x7fELF" or d[4] != 1 or d[5] != 1 or struct.unpack_from("<H", d, 18)[0] != 40:
        raise ToolError("%s: not a 32-bit little-endian ARM ELF" % path)
    shoff, = struct.unpack_from("<I", d, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", d, 0x2E)
    hdrs = [struct.unpack_from("<10I", d, shoff + i * shentsize) for i in range(shnum)]
    stroff = hdrs[shstrndx][4]
    out = {}
    for h in hdrs:
        name = d[stroff + h[0]:d.index(b"\0", stroff + h[0])].decode()
        out[name] = (h[3], h[5], h[2], d[h[4]:h[4] + h[5]] if h[1] != 8 else b"")
    return out


def clean(name):
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    name = re.sub(r"(^|::|<)_\$", r"\1$", name).replace("..", "::")
    esc = {"LT": "<", "GT": ">", "C": ",", "RF": "&", "BP": "*", "SP": "@", "LP": "(", "RP": ")"}
    return re.sub(r"\$(LT|GT|C|RF|BP|SP|LP|RP|u[0-9a-f]{2})\$",
                  lambda m: esc.get(m.group(1)) or chr(int(m.group(1)[1:], 16)), name)


def regs_of(text):
    """Registers named in a register list such as {r4-r7, lr} or {d8-d15}."""
    out = []
    for part in text.strip("{} ").split(","):
        m = re.match(r"\s*([a-z]+)(\d+)\s*-\s*[a-z]+(\d+)", part)
        out += ["%s%d" % (m.group(1), i) for i in range(int(m.group(2)), int(m.group(3)) + 1)] if m \
            else [part.strip()]
    return [REGALIAS.get(r, r) for r in out if r]


def core_reg(tok):
    tok = REGALIAS.get(tok.strip(), tok.strip())
    return tok if re.match(r"^(r\d+|lr)$", tok) else None


def writes(mn, ops):
    """Core registers an instruction writes (rough, enough for the backward constant scan)."""
    base = re.sub(r"(\.w|\.n)$", "", mn)
    w = set()
    m = re.search(r"\[(\w+)(?:, [^\]]*)?\](!|, #)", ops) or re.match(r"(\w+)!", ops)
    if m:
        w.add(REGALIAS.get(m.group(1), m.group(1)))
    if base.startswith(("pop", "ldm")):
        return w | set(regs_of(ops[ops.find("{"):]))
    if re.match(r"(cmp|cmn|tst|teq|it|b|push|vpush|stm|vst|pld|dmb|dsb|isb|nop|msr|cps|wf|sev|udf|bkpt|svc)", base) \
            or (base.startswith("str") and not base.startswith("strex")):
        return w
    n = 2 if re.match(r"(ldrd|ldrexd|umull|smull|umlal|smlal|vmov)", base) else 1
    for tok in ops.split("[")[0].split(",")[:n]:
        if not core_reg(tok):
            break
        w.add(core_reg(tok))
    return w


def resolve_reg(body, i, reg, starts):
    """Function addresses reg holds at body[i], when only movw/movt/mov define it; else None."""
    tracked, hi, found = {reg}, {}, set()
    for _, mn, ops in reversed(body[:i]):
        for r in writes(mn, ops) & tracked:
            cond = re.match(r"^mov[wt]?%s(\.w)?$" % COND, mn)
            m = re.match(r"^(mov[wt]?)(?:%s)?(?:\.w)?$" % COND, mn)
            imm = re.match(r"\w+, #(0x[0-9a-f]+|\d+)$", ops)
            src = re.match(r"\w+, (r\d+|ip|sb|sl|fp)$", ops)
            if m and m.group(1) == "movt" and imm:
                hi[r] = int(imm.group(1), 0)
            elif m and imm and r in hi:
                found.add(hi.pop(r) << 16 | int(imm.group(1), 0))
                if not cond:
                    tracked.discard(r)
            elif m and m.group(1) == "mov" and src:
                tracked.add(REGALIAS.get(src.group(1), src.group(1)))
                if not cond:
                    tracked.discard(r)
            else:
                return None
        if not tracked:
            break
    if tracked or not found or any(a & 1 == 0 or (a & ~1) not in starts for a in found):
        return None
    return {a & ~1 for a in found}


def analyse(elf, tool):
    syms, funcs = {}, {}
    for line in objdump(tool, "-t", "-C", elf).splitlines():
        m = re.match(r"^([0-9a-f]{8}) (.{7}) (\S+)\s+([0-9a-f]+) (.+)$", line)
        if not m:
            continue
        addr, flags, name = int(m.group(1), 16), m.group(2), m.group(5)
        syms.setdefault(name, addr)
        if "F" in flags:
            f = funcs.setdefault(addr, {"addr": addr, "size": 0, "aliases": [], "body": []})
            f["size"] = max(f["size"], int(m.group(4), 16))
            f["aliases"].append(("l" in flags[:1], clean(name)))
    if not funcs:
        raise ToolError("no FUNC symbols in %s" % elf)
    starts = sorted(funcs)
    for i, a in enumerate(starts):
        f = funcs[a]
        f["end"] = a + f["size"] if f["size"] else (starts[i + 1] if i + 1 < len(starts) else a + 2)
        f["aliases"] = [n for _, n in sorted(set(f["aliases"]), key=lambda x: (x[0], len(x[1])))]
    count = {}
    for f in funcs.values():
        count[f["aliases"][0]] = count.get(f["aliases"][0], 0) + 1
    for f in funcs.values():
        f["name"] = f["aliases"][0] + ("@%#x" % f["addr"] if count[f["aliases"][0]] > 1 else "")
    for line in objdump(tool, "-d", "--no-show-raw-insn", "-C", elf).splitlines():
        m = re.match(r"^\s*([0-9a-f]+):\s+(?:(?:[0-9a-f]{2} )+\s*)?(\S+)\s*(.*?)(?:\s+@ .*)?$", line)
        if not m or m.group(2).startswith("."):
            continue
        a = int(m.group(1), 16)
        k = bisect.bisect_right(starts, a) - 1
        if k >= 0 and a < funcs[starts[k]]["end"]:
            funcs[starts[k]]["body"].append((a, m.group(2), m.group(3)))
    for f in funcs.values():
        frame_and_calls(f, funcs, starts)
    return syms, funcs


def frame_and_calls(f, funcs, starts):
    f.update(prologue=0, total=0, largest=0, dynamic=False, calls={}, indirect=[])
    consts, in_prologue = {}, True
    for i, (a, mn, ops) in enumerate(f["body"]):
        base = re.sub(r"(\.w|\.n)$", "", mn)
        dec = 0
        if base in ("push", "vpush") or (base in ("stmdb", "stmfd", "vstmdb") and ops.startswith("sp!")):
            dec = sum(8 if r.startswith("d") else 4 for r in regs_of(ops[ops.find("{"):]))
        elif re.match(r"^subw?s?$", base) and re.match(r"sp, (sp, )?", ops):
            arg = re.sub(r"^sp, (sp, )?", "", ops)
            if arg.startswith("#"):
                dec = int(arg[1:], 0)
            elif REGALIAS.get(arg, arg) in consts:
                dec = consts[REGALIAS.get(arg, arg)]
            else:
                f["dynamic"] = True
        elif base.startswith("str") and re.search(r"\[sp, #-(\w+)\]!$", ops):
            dec = int(re.search(r"\[sp, #-(\w+)\]!$", ops).group(1), 0)
        m = re.match(r"^(r\d+|ip), #(0x[0-9a-f]+|\d+)$", ops)
        if m and base in ("movw", "mov", "movs"):
            consts[REGALIAS.get(m.group(1), m.group(1))] = int(m.group(2), 0)
        elif m and base == "movt":
            r = REGALIAS.get(m.group(1), m.group(1))
            consts[r] = (consts.get(r, 0) & 0xFFFF) | int(m.group(2), 0) << 16
        f["total"] += dec
        f["largest"] = max(f["largest"], dec)
        br = BRANCH.match(mn)
        inc = base.startswith(("pop", "vpop", "ldm")) or "[sp], #" in ops or \
            (re.match(r"^addw?s?$", base) and ops.startswith("sp,"))
        if in_prologue and (br or inc):
            in_prologue = False
        elif in_prologue:
            f["prologue"] += dec
        tgt = re.match(r"^(0x[0-9a-f]+)", ops)
        if br and br.group(1) in ("bl", "blx") and tgt:
            t = int(tgt.group(1), 16)
            k = bisect.bisect_right(starts, t) - 1
            if k >= 0:
                f["calls"].setdefault(starts[k], "call")
        elif br and br.group(1) == "b" and tgt:
            t = int(tgt.group(1), 16)
            if not f["addr"] <= t < f["end"] and t in funcs:
                f["calls"].setdefault(t, "tail")
        elif is_indirect(br, base, ops):
            targets = resolve_reg(f["body"], i, core_reg(ops), funcs) if br else None
            if targets:
                for t in targets:
                    f["calls"].setdefault(t, "const")
            else:
                f["indirect"].append("%#x: %s %s" % (a, mn, ops))
    f["frame"] = max(f["prologue"], f["total"])


def is_indirect(br, base, ops):
    """A call or jump through a register or memory (returns excluded)."""
    if br:
        return br.group(1) in ("blx", "bx") and ops != "lr" and not ops.startswith("0x")
    if base.startswith("pop") or (base.startswith("ldm") and ops.startswith("sp!")):
        return False  # pop {.., pc} / ldmia sp!, {.., pc}: return
    if base.startswith("ldr") and ops.startswith("pc, [sp], #"):
        return False  # ldr pc, [sp], #4: return
    return (base.startswith(("ldr", "mov")) and ops.startswith("pc,")) or \
        (base.startswith("ldm") and re.search(r"\bpc\}", ops) is not None)


def build_graph(funcs, rules):
    for f in funcs.values():
        f["rule_edges"] = set()
        matched = False
        for caller, callee in rules:
            if f["indirect"] and any(caller in n for n in f["aliases"]):
                matched = True
                f["rule_edges"] |= {g["addr"] for g in funcs.values()
                                    if any(callee in n for n in g["aliases"])}
        f["covered"] = matched
        for t in f["rule_edges"]:
            f["calls"].setdefault(t, "indirect rule")


def sccs(funcs):
    """Tarjan's algorithm, iterative; returns the components in reverse topological order."""
    index, low, on, stack, out, n = {}, {}, set(), [], [], [0]
    for root in funcs:
        if root in index:
            continue
        work = [(root, iter(funcs[root]["calls"]))]
        index[root] = low[root] = n[0]; n[0] += 1; stack.append(root); on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = n[0]; n[0] += 1; stack.append(w); on.add(w)
                    work.append((w, iter(funcs[w]["calls"])))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop(); on.discard(w); comp.append(w)
                        if w == v:
                            break
                    out.append(comp)
    return out


def depths(funcs, allow):
    comp_of, depth, best, cycles = {}, {}, {}, []
    for comp in sccs(funcs):
        cid = min(comp)
        for v in comp:
            comp_of[v] = cid
        cyclic = len(comp) > 1 or comp[0] in funcs[comp[0]]["calls"]
        if cyclic:
            names = sorted(funcs[v]["name"] for v in comp)
            cycles.append({"functions": names, "allowed": any(s in n for s in allow for v in comp
                                                              for n in funcs[v]["aliases"])})
        out = [(depth[comp_of[w]], w) for v in comp for w in funcs[v]["calls"] if comp_of.get(w) != cid]
        sub = max(out, default=(0, None))
        depth[cid] = sum(funcs[v]["frame"] for v in comp) + sub[0]
        best[cid] = (sorted(comp, key=lambda v: -funcs[v]["frame"]) if cyclic else comp, sub[1])
    return comp_of, depth, best, cycles


def path_of(root, comp_of, best, funcs):
    path, v, via = [], root, "root"
    while v is not None:
        members, nxt = best[comp_of[v]]
        cyc = len(members) > 1 or v in funcs[v]["calls"]
        path += [{"function": funcs[m]["name"], "frame": funcs[m]["frame"],
                  "via": "cycle member" if cyc and m != v else via} for m in members]
        via = next((funcs[m]["calls"][nxt] for m in members if nxt in funcs[m]["calls"]), None)
        v = nxt
    return path


def reachable(root, funcs):
    seen, todo = {root}, [root]
    while todo:
        for w in funcs[todo.pop()]["calls"]:
            if w not in seen:
                seen.add(w); todo.append(w)
    return seen


def stack_region(sections, syms, ram_origin):
    top = syms.get("_stack_start")
    if top is None:
        raise ToolError("no _stack_start symbol")
    ram = [(a, a + s) for n, (a, s, fl, _) in sections.items() if fl & 3 == 3 and s and a >= ram_origin]
    lo, hi = min(a for a, _ in ram), max(e for _, e in ram)
    end = syms.get("_stack_end")
    if top <= lo:
        bottom = end if end is not None and end < top else ram_origin
        return "flip-link (stack at the bottom of RAM, below .data/.bss)", bottom, top
    if top >= hi:
        bottom = max(hi, end if end is not None and end <= top else hi)
        return "cortex-m-rt default, no flip-link (stack at the top of RAM, grows into .bss)", bottom, top
    raise ToolError("_stack_start %#x lies inside the RAM sections [%#x, %#x)" % (top, lo, hi))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("elf")
    ap.add_argument("--max-frame", type=int, default=4096)
    ap.add_argument("--min-headroom", type=int, default=8192)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--indirect", action="append", default=[], metavar="CALLER=CALLEE")
    ap.add_argument("--allow-cycle", action="append", default=[], metavar="SUBSTR")
    ap.add_argument("--priority", action="append", default=[], metavar="HANDLER=N")
    ap.add_argument("--ram-origin", type=lambda s: int(s, 0), default=0x20000000)
    a = ap.parse_args()
    rules, prio = list(DEFAULT_RULES), dict(DEFAULT_PRIO)
    for spec, kind in [(s, "indirect") for s in a.indirect] + [(s, "priority") for s in a.priority]:
        k, sep, v = spec.partition("=")
        if not sep or not k or not v or (kind == "priority" and not (v.isdigit() and int(v) <= 15)):
            ap.error("bad --%s %r" % (kind, spec))
        if kind == "indirect":
            rules.append((k, v))
        else:
            prio[k] = int(v)
    try:
        tool = find_objdump()
        sections = read_sections(a.elf)
        syms, funcs = analyse(a.elf, tool)
        layout, bottom, top = stack_region(sections, syms, a.ram_origin)
        vt = sections.get(".vector_table")
        if not vt or len(vt[3]) < 8:
            raise ToolError("no .vector_table section")
    except (ToolError, OSError) as e:
        print("stack-check: error: %s" % e, file=sys.stderr)
        return 2
    build_graph(funcs, rules)
    comp_of, depth, best, cycles = depths(funcs, DEFAULT_ALLOW + a.allow_cycle)
    words = struct.unpack_from("<%dI" % (len(vt[3]) // 4), vt[3])
    default = {syms.get(n) for n in ("DefaultHandler", "DefaultHandler_")} - {None}
    roots, seen = [], set()
    for slot, w in enumerate(words[1:], 1):
        addr = w & ~1
        if not w & 1 or addr in default or addr in seen or addr not in funcs:
            continue
        seen.add(addr)
        names = [n for n in funcs[addr]["aliases"] if re.match(r"^[A-Z][A-Z0-9_]*$", n)]
        name = EXC_NAMES.get(slot) if 2 <= slot < 16 else (names[0] if names else funcs[addr]["name"])
        if slot == 1:
            level, p = ("thread",), "thread"
        elif slot in (2, 3):
            level, p = ("fixed", slot), "fixed (%s)" % ("-2" if slot == 2 else "-1")
        else:
            p = next((prio[n] for n in [name] + funcs[addr]["aliases"] if n in prio), None)
            level = ("prio", p) if p is not None else ("own", name)
        d = depth[comp_of[addr]]
        roots.append({"root": name, "function": funcs[addr]["name"], "priority": p, "level": level,
                      "depth_bytes": d, "exception_frame_bytes": 0 if slot == 1 else EXC_FRAME,
                      "path": path_of(addr, comp_of, best, funcs),
                      "unresolved_indirect": sorted("%s: %s" % (funcs[v]["name"], c) for v in reachable(addr, funcs)
                                                    if not funcs[v]["covered"] for c in funcs[v]["indirect"])})
    levels = {}
    for r in roots:
        cost = r["depth_bytes"] + r["exception_frame_bytes"]
        if r["level"] not in levels or cost > levels[r["level"]][0]:
            levels[r["level"]] = (cost, r["root"])
    worst = sum(c for c, _ in levels.values())
    stack = top - bottom
    headroom = stack - worst
    frames = sorted(funcs.values(), key=lambda f: -f["frame"])
    big = [f for f in frames if f["frame"] > a.max_frame]
    dyn = [f["name"] for f in funcs.values() if f["dynamic"]]
    probe = [f["name"] for f in funcs.values() if "probestack" in f["name"]]
    bad_cycles = [c for c in cycles if not c["allowed"]]
    unresolved = sorted({u for r in roots for u in r["unresolved_indirect"]})
    if ("thread",) not in levels:
        print("stack-check: error: no reset vector in .vector_table", file=sys.stderr)
        return 2
    fail = bool(big or dyn or bad_cycles or headroom < a.min_headroom)
    order = sorted(levels, key=lambda k: ({"thread": 0, "prio": 1, "own": 2, "fixed": 3}[k[0]],
                                          -k[1] if k[0] == "prio" else 0, str(k)))
    if a.json:
        print(json.dumps({
            "stack_bytes": stack, "worst_case_bytes": worst, "headroom_bytes": headroom, "layout": layout,
            "stack_region": [hex(bottom), hex(top)], "ok": not fail,
            "largest_frames": [{"function": f["name"], "bytes": f["frame"], "prologue": f["prologue"],
                                "largest_single": f["largest"]} for f in frames[:10]],
            "over_max_frame": [{"function": f["name"], "bytes": f["frame"]} for f in big],
            "roots": [{k: r[k] for k in ("root", "function", "priority", "depth_bytes",
                                         "exception_frame_bytes", "path", "unresolved_indirect")} for r in roots],
            "levels": [{"level": " ".join(map(str, k)), "root": levels[k][1], "bytes": levels[k][0]} for k in order],
            "unresolved_indirect": unresolved, "cycles": cycles, "dynamic_sp": dyn, "probestack": probe}, indent=1))
        return 1 if fail else 0
    print("stack-check %s" % a.elf)
    print("layout: %s\nstack: [%#010x, %#010x) = %d bytes" % (layout, bottom, top, stack))
    print("\nlargest frames (frame = all sp decrements; prologue sum / largest single decrement):")
    for f in frames[:10]:
        print("  %7d  %s  (prologue %d, largest %#x)" % (f["frame"], f["name"], f["prologue"], f["largest"]))
    for f in big:
        print("FAIL frame %d > --max-frame %d: %s" % (f["frame"], a.max_frame, f["name"]))
    for n in dyn:
        print("FAIL sp lowered by an unknown register (dynamic stack): %s" % n)
    for n in probe:
        print("note: stack probe present: %s" % n)
    for c in cycles:
        print("%s cycle: %s" % ("allowed" if c["allowed"] else "FAIL", ", ".join(c["functions"])))
    for r in roots:
        print("\nroot %s (%s), priority %s: depth %d bytes%s" % (
            r["root"], r["function"], r["priority"], r["depth_bytes"],
            " + exception frame %d" % r["exception_frame_bytes"] if r["exception_frame_bytes"] else ""))
        for i, s in enumerate(r["path"]):
            via = "" if s["via"] in ("call", "root") else "  [%s]" % s["via"]
            print("  %s%5d  %s%s" % ("  " * min(i, 12), s["frame"], s["function"], via))
        for u in r["unresolved_indirect"]:
            print("  NOT COVERED indirect call in %s" % u)
    print("\nworst case = sum over levels:")
    for k in order:
        print("  %-24s %7d  (%s)" % (" ".join(map(str, k)), levels[k][0], levels[k][1]))
    print("  %-24s %7d\nheadroom: %d - %d = %d bytes (minimum %d)" % ("total", worst, stack, worst, headroom, a.min_headroom))
    if headroom < a.min_headroom:
        print("FAIL headroom %d < --min-headroom %d" % (headroom, a.min_headroom))
    print("\nstack-check: %s" % ("FAIL" if fail else "ok"))
    return 1 if fail else 0


if __name__ == "__main__":
    sys.exit(main())
