-- ---- the dissector: framing, frame checks and fields (hand-written, over the tables above) ----------

local xac1 = Proto("xac1", "XA-C1 actuator controller protocol")
local verdicts = Proto("xac1_verdicts", "XA-C1 verdicts (xac1 recording)")

local pf = {
  frame = ProtoField.string("xac1.frame", "Frame"),
  header = ProtoField.string("xac1.header", "Header"),
  role = ProtoField.string("xac1.role", "Role"),
  meaning = ProtoField.string("xac1.meaning", "Meaning"),
  check = ProtoField.string("xac1.check", "Frame check"),
  junk = ProtoField.bytes("xac1.junk", "Junk (bytes that form no frame)"),
  junk_reason = ProtoField.string("xac1.junk_reason", "Why junk"),
  spans = ProtoField.string("xac1.spans", "Reassembled from packets"),
}
local field_pf = {}
for _, name in ipairs(FIELD_ORDER) do
  local f = FIELDS[name]
  local abbrev = "xac1." .. f.abbrev
  local label = f.label
  if f.text then
    field_pf[name] = ProtoField.string(abbrev, label)
  elseif name == "code" then
    field_pf[name] = ProtoField.uint8(abbrev, label, base.HEX, ALARMS)
  elseif f.width > 2 then
    field_pf[name] = ProtoField.uint32(abbrev, label, base.HEX_DEC)
  elseif f.radix == 16 then
    field_pf[name] = ProtoField.uint8(abbrev, label, base.HEX_DEC)
  else
    field_pf[name] = ProtoField.uint8(abbrev, label, base.DEC)
  end
end
local list = {}
for _, v in pairs(pf) do list[#list + 1] = v end
for _, v in pairs(field_pf) do list[#list + 1] = v end
xac1.fields = list

local vf = {
  record = ProtoField.uint32("xac1.record", "Record with the violation (xac1 decode's i)"),
  violation = ProtoField.string("xac1.violation", "Violation"),
  side = ProtoField.string("xac1.side", "Whose fault"),
  detail = ProtoField.string("xac1.detail", "Detail"),
  reply_to = ProtoField.uint32("xac1.reply_to", "Answers record"),
  latency_ms = ProtoField.double("xac1.latency_ms", "Latency (ms)"),
  pieces = ProtoField.string("xac1.pieces", "Read in pieces (one frame's bytes, as they came)"),
}
verdicts.fields = { vf.record, vf.violation, vf.side, vf.detail, vf.reply_to, vf.latency_ms, vf.pieces }

local function expert_name(code) return (code:gsub("%-", "_")) end
local check_expert, verdict_expert = {}, {}
local check_list, verdict_list = {}, {}
for _, v in ipairs(VIOLATIONS) do
  local sev = v.severity == "error" and expert.severity.ERROR or expert.severity.NOTE
  check_expert[v.code] = ProtoExpert.new("xac1.check." .. expert_name(v.code), v.code .. ": " .. v.meaning,
                                         expert.group.PROTOCOL, sev)
  verdict_expert[v.code] = ProtoExpert.new("xac1.verdict." .. expert_name(v.code),
                                           v.code .. ": " .. v.meaning, expert.group.SEQUENCE, sev)
  check_list[#check_list + 1] = check_expert[v.code]
  verdict_list[#verdict_list + 1] = verdict_expert[v.code]
end
local verdict_other = ProtoExpert.new("xac1.verdict.other", "xac1 verdict", expert.group.SEQUENCE,
                                      expert.severity.WARN)
verdict_list[#verdict_list + 1] = verdict_other
xac1.experts = check_list
verdicts.experts = verdict_list

local f_comment = Field.new("frame.comment")

-- ---- framing: a port of xac1_proto/framer.py (bytes -> frames and junk, whatever the chunking) -----

local ZERO, LETTER_O, LF = LEAD:byte(), LETTER_O_CHAR:byte(), 10
local UNDECIDED = -2

local function headerish(b)
  return b ~= nil and ((b >= 65 and b <= 90) or (b >= 97 and b <= 122) or b == 37)
end

local function strong_start(buf, p)
  local b = buf:byte(p)
  if b ~= ZERO and b ~= LETTER_O then return 0 end
  local tail = buf:sub(p + 1, p + 2)
  if #tail == 2 then return TAILS[tail] and 1 or 0 end
  if #tail == 0 then return UNDECIDED end
  if SECOND[tail:byte(1)] then return UNDECIDED end
  return 0
end

local function weak_start(buf, p)
  local b = buf:byte(p)
  if b == ZERO then
    if p + 1 > #buf then return UNDECIDED end
    return headerish(buf:byte(p + 1)) and 1 or 0
  end
  if b == LETTER_O then return strong_start(buf, p) end
  return 0
end

-- A framer: .buf (pending bytes), .base (stream offset of buf's first byte), .first (packet number
-- and time of each pending byte's packet, as {offset_end, packet} runs).
local function new_framer() return { buf = "", base = 0, runs = {}, last_t = nil } end

local function packet_at(fr, offset)
  for _, run in ipairs(fr.runs) do
    if offset < run[1] then return run[2] end
  end
  return nil
end

local function emit(fr, n, reason, out)
  local raw = fr.buf:sub(1, n)
  local ev = { raw = raw, offset = fr.base, reason = reason,
               first_packet = packet_at(fr, fr.base), last_packet = packet_at(fr, fr.base + n - 1) }
  fr.buf = fr.buf:sub(n + 1)
  fr.base = fr.base + n
  while #fr.runs > 0 and fr.runs[1][1] <= fr.base do table.remove(fr.runs, 1) end
  out[#out + 1] = ev
  return ev
end

local function frame_candidate(fr, final, out)
  local buf = fr.buf
  local lf = buf:find("\n", 1, true)
  if lf ~= nil and lf > MAX_FRAME then lf = nil end
  local limit = lf and (lf - 1) or math.min(#buf, MAX_FRAME)
  for p = 1, limit - 1 do
    local found = strong_start(buf, p + 1)
    if found == 1 then return emit(fr, p, "truncated", out) end
    if found == UNDECIDED and not final then return nil end
  end
  if lf then return emit(fr, lf, nil, out) end
  if #buf >= MAX_FRAME then return emit(fr, MAX_FRAME, "overflow", out) end
  if final then return emit(fr, #buf, "flushed", out) end
  return nil
end

local function junk_run(fr, final, out)
  local buf = fr.buf
  local limit = math.min(#buf, MAX_FRAME)
  for p = 1, limit - 1 do
    if buf:byte(p) == LF then return emit(fr, p, "no-frame-start", out) end
    local found = weak_start(buf, p + 1)
    if found == 1 then return emit(fr, p, "no-frame-start", out) end
    if found == UNDECIDED and not final then return nil end
  end
  if buf:byte(limit) == LF or #buf >= MAX_FRAME or final then
    return emit(fr, limit, "no-frame-start", out)
  end
  return nil
end

local function drain(fr, final, out)
  while #fr.buf > 0 do
    local start = weak_start(fr.buf, 1)
    if start == UNDECIDED and not final then return end
    local ev
    if start == 1 then ev = frame_candidate(fr, final, out) else ev = junk_run(fr, final, out) end
    if ev == nil then return end
  end
end

local function feed(fr, data, packet, out)
  if #data > 0 then
    fr.buf = fr.buf .. data
    fr.runs[#fr.runs + 1] = { fr.base + #fr.buf, packet }
  end
  drain(fr, false, out)
end

-- ---- frame checks: a port of xac1_proto/codec.py's diagnose over the generated layouts -----------

local function add(out, code, at, text) out[#out + 1] = { code = code, offset = at, text = text } end

local function find_spec(raw, role, out)
  local head = raw:sub(1, HEADER_WIDTH)
  local fs = SPECS[role][head]
  if fs then return fs end
  local lead_o = raw:sub(1, 1) == LETTER_O_CHAR
  if lead_o then
    fs = SPECS[role][LEAD .. head:sub(2)]
    if fs then
      add(out, "letter-o", 0, fs.header .. " " .. role .. ": byte 0: the letter O, not the digit 0")
      return fs
    end
  end
  -- docs/protocol.md "Framing": a header in lower case (0rv) is read as its command, with a notice
  local upper = head:upper()
  fs = SPECS[role][lead_o and (LEAD .. upper:sub(2)) or upper]
  if fs and not head:find("[\128-\255]") then
    if lead_o then
      add(out, "letter-o", 0, fs.header .. " " .. role .. ": byte 0: the letter O, not the digit 0")
    end
    local at = 1
    while at < HEADER_WIDTH and head:sub(at + 1, at + 1) == fs.header:sub(at + 1, at + 1) do at = at + 1 end
    add(out, "lowercase-hex", at, fs.header .. " " .. role .. ": byte " .. at .. ": expected the header " ..
        fs.header .. " in upper case, got " .. string.format("%q", head))
    return fs
  end
  add(out, "unknown-command", 0, role .. ": " .. string.format("%q", head) .. " is no " .. role .. " header")
  return nil
end

local function split_terminator(raw, fs, out)
  local where = fs.header .. " " .. fs.role
  if raw:sub(-2) == TERMINATOR then return raw:sub(1, -3) end
  if raw:sub(-1) == "\n" then
    if #raw == fs.length and #raw >= 2 then
      add(out, "bad-terminator", #raw - 2, where .. ": byte " .. (#raw - 2) .. ": expected CR LF")
      return raw:sub(1, -3)
    end
    add(out, "bad-terminator", #raw - 1, where .. ": byte " .. (#raw - 1) .. ": a bare LF, expected CR LF")
    return raw:sub(1, -2)
  end
  add(out, "bad-terminator", #raw, where .. ": byte " .. #raw .. ": no CR LF at the end")
  return raw
end

local function has(out, code)
  for _, v in ipairs(out) do if v.code == code then return true end end
  return false
end

local function decode_field(item, raw, at, fs, out)
  local f = FIELDS[item.field]
  local where = fs.header .. " " .. fs.role .. ": byte " .. at .. ": " .. f.label
  if #raw < f.width then
    if not has(out, "bad-length") then add(out, "bad-length", at, where .. ": the frame ends early") end
    return nil
  end
  local digits = f.radix == 16 and "^[0-9A-Fa-f]+$" or "^[0-9]+$"
  if not raw:match(digits) then
    add(out, "field-range", at, where .. ": " .. string.format("%q", raw) .. " is not " ..
        (f.radix == 16 and "hex" or "decimal") .. " digits")
    return nil
  end
  local value = f.text and raw or tonumber(raw, f.radix)
  if f.radix == 16 and raw ~= raw:upper() then
    add(out, "lowercase-hex", at, where .. ": " .. raw .. " in lower case")
  end
  if not f.text and (value < item.lo or value > item.hi) then
    add(out, "field-range", at, string.format("%s: %s out of range %s", where, raw, item.range))
  end
  if item.field == "code" and fs.header == ALARM_HEADER then
    if RESERVED_ALARMS[value] then
      add(out, "reserved-alarm", at, where .. ": alarm " .. raw .. " has no meaning in the vendor text")
    elseif ALARMS[value] == nil then
      add(out, "unknown-alarm", at, where .. ": alarm " .. raw .. " is not in the vendor's list")
    end
  end
  return value
end

local function walk(body, fs, out)
  local values, places = {}, {}
  local at = HEADER_WIDTH
  local short = (fs.length - #TERMINATOR) - #body
  local ok = true
  for _, item in ipairs(fs.layout) do
    if item.literal then
      local seen = body:sub(at + 1, at + #item.literal)
      local skip = false
      if seen ~= item.literal then
        add(out, item.code, at, fs.header .. " " .. fs.role .. ": byte " .. at .. ": expected '" ..
            item.literal .. "', got " .. string.format("%q", seen))
        if short >= #item.literal then
          short = short - #item.literal
          skip = true
        end
      end
      if not skip then at = at + #item.literal end
    else
      local w = FIELDS[item.field].width
      local raw = body:sub(at + 1, at + w)
      local value = decode_field(item, raw, at, fs, out)
      if value == nil then ok = false else values[item.field] = value; places[item.field] = at end
      at = at + w
    end
  end
  return values, places, ok
end

local function diagnose(raw, role)
  local out = {}
  local fs = find_spec(raw, role, out)
  if fs == nil then return nil, {}, {}, false, out end
  if #raw ~= fs.length then
    add(out, "bad-length", math.min(#raw, fs.length), fs.header .. " " .. role .. ": " .. #raw ..
        " bytes, expected " .. fs.length)
  end
  local body = split_terminator(raw, fs, out)
  local values, places, ok = walk(body, fs, out)
  table.sort(out, function(a, b)
    local oa, ob = CHECK_ORDER[a.code] or 9, CHECK_ORDER[b.code] or 9
    if oa ~= ob then return oa < ob end
    return a.offset < b.offset
  end)
  return fs, values, places, ok, out
end

-- ---- per-capture state (first pass), kept per packet for later passes -----------------------------

local framers, last_dir, results, dirs
local IDLE_FLUSH_S = DEVICE_IDLE_FLUSH_S

local function reset()
  framers = { host = new_framer(), device = new_framer() }
  last_dir = nil
  results = {}
  dirs = {}
end
reset()
xac1.init = reset

local DATA_EVENTS = { [1] = "host", [3] = "host", [2] = "device", [4] = "device" }

local function show_text(raw)
  return (raw:gsub("\r", "\\r"):gsub("\n", "\\n"):gsub("[^\32-\126\\]", function(c)
    return string.format("\\x%02X", c:byte())
  end))
end

local function add_event(tree, tvb, pinfo, ev, info)
  local local_off = ev.offset - ev.packet_base
  local range
  if ev.first_packet == pinfo.number and local_off >= 0 and local_off + #ev.raw <= tvb:len() then
    range = tvb(local_off, #ev.raw)
  else
    range = ByteArray.new(ev.raw, true):tvb("XA-C1 frame"):range()
  end
  if ev.reason ~= nil then
    local t = tree:add(xac1, range, "XA-C1 junk (" .. ev.reason .. "): " .. show_text(ev.raw))
    t:add(pf.junk, range)
    t:add(pf.junk_reason, ev.reason)
    t:add(pf.check, "garbage")
    t:add_proto_expert_info(check_expert["garbage"], #ev.raw .. " bytes that form no frame (" .. ev.reason .. ")")
    info[#info + 1] = "junk"
    return
  end
  local role = ev.dir == "host" and "command" or "answer"
  local fs, values, places, ok, found = diagnose(ev.raw, role)
  if not ok then values = {} end  -- as xac1 decode: no fields when one cannot be read
  local summary = (fs and fs.header or "?") .. " " .. role
  for _, name in ipairs(fs and fs.fields or {}) do
    if values[name] ~= nil then
      local f = FIELDS[name]
      local v = values[name]
      summary = summary .. " " .. f.label .. "=" .. (f.text and v or string.format(f.fmt, v))
    end
  end
  local t = tree:add(xac1, range, "XA-C1 " .. summary)
  t:add(pf.frame, range, show_text(ev.raw))
  if ev.first_packet ~= ev.last_packet then
    t:add(pf.spans, ev.first_packet .. "-" .. ev.last_packet)
  end
  if fs then
    t:add(pf.header, range:range(0, math.min(HEADER_WIDTH, range:len())), fs.header)
    t:add(pf.role, role)
    t:add(pf.meaning, fs.meaning)
    for _, name in ipairs(fs.fields) do
      local v = values[name]
      if v ~= nil then
        local f = FIELDS[name]
        local at = places[name]
        local sub = range:range(math.min(at, range:len()), math.min(f.width, math.max(0, range:len() - at)))
        local item = t:add(field_pf[name], sub, v)
        item:append_text(" (" .. f.doc .. ")")
      end
    end
  else
    t:add(pf.role, role)
  end
  local said = {}
  for _, v in ipairs(found) do  -- each code once a frame, as xac1 decode lists them
    if not said[v.code] then
      said[v.code] = true
      t:add(pf.check, v.code)
      t:add_proto_expert_info(check_expert[v.code], v.code .. ": " .. v.text)
    end
  end
  info[#info + 1] = summary .. (#found > 0 and (" [" .. found[1].code .. (#found > 1 and ", ..." or "") .. "]") or "")
end

function xac1.dissector(tvb, pinfo, tree)
  local events = results[pinfo.number]
  if events == nil and not pinfo.visited then
    local d = dirs[pinfo.number] or last_dir or "host"
    events = {}
    local t = pinfo.abs_ts
    local dev = framers.device
    if IDLE_FLUSH_S and #dev.buf > 0 and dev.last_t ~= nil and t - dev.last_t >= IDLE_FLUSH_S then
      local flushed = {}
      drain(dev, true, flushed)
      for _, ev in ipairs(flushed) do ev.dir = "device"; ev.packet_base = -1; events[#events + 1] = ev end
    end
    local fr = framers[d]
    local base = fr.base + #fr.buf
    local out = {}
    feed(fr, tvb:raw(), pinfo.number, out)
    if d == "device" and tvb:len() > 0 then fr.last_t = t end
    for _, ev in ipairs(out) do ev.dir = d; ev.packet_base = base; events[#events + 1] = ev end
    results[pinfo.number] = events
  end
  events = events or {}
  pinfo.cols.protocol = "XA-C1"
  local info = {}
  for _, ev in ipairs(events) do add_event(tree, tvb, pinfo, ev, info) end
  local arrow = (dirs[pinfo.number] == "host") and "host > " or "device > "
  if #info > 0 then
    pinfo.cols.info = arrow .. table.concat(info, " | ")
  else
    pinfo.cols.info = arrow .. "(part of a frame: " .. tvb:len() .. " bytes)"
  end
  return tvb:len()
end

-- ---- our verdicts: packet comments written by xac1 (sniffer/io/pcapng_writer.py) ---------------

function verdicts.dissector(tvb, pinfo, tree)
  local comments = { f_comment() }
  local sub = nil
  local shown, codes = {}, {}  -- the recorded codes, each once, for the Info column
  for _, c in ipairs(comments) do
    local text = tostring(c.value)
    if text:sub(1, #COMMENT_PREFIX) == COMMENT_PREFIX then
      sub = sub or tree:add(verdicts, tvb(0, 0), "XA-C1 verdicts (from the recording)")
      local i, code, side, sentence = text:match("^xac1 #(%d+) ([%w%-]+) %((%a+)%): (.*)$")
      if text:sub(1, #PIECES_PREFIX) == PIECES_PREFIX then
        sub:add(vf.pieces, tvb(0, 0), text:sub(#PIECES_PREFIX + 1))
      elseif i then
        local item = sub:add(vf.violation, tvb(0, 0), code)
        item:append_text(" (" .. side .. ", record #" .. i .. ")")
        sub:add(vf.record, tvb(0, 0), tonumber(i))
        sub:add(vf.side, tvb(0, 0), side)
        sub:add(vf.detail, tvb(0, 0), sentence)
        item:add_proto_expert_info(verdict_expert[code] or verdict_other, code .. " (" .. side .. "): " .. sentence)
        if not shown[code] then shown[code] = true; codes[#codes + 1] = code end
      else
        local r, j, rest = text:match("^xac1 #(%d+) reply_to=#(%d+)(.*)$")
        if r then
          sub:add(vf.reply_to, tvb(0, 0), tonumber(j)):append_text(" (this is record #" .. r .. ")")
          local ms = rest:match("latency_ms=([%d%.]+)")
          if ms then sub:add(vf.latency_ms, tvb(0, 0), tonumber(ms)) end
        end
      end
    end
  end
  if #codes > 0 then pinfo.cols.info:append(" {recorded: " .. table.concat(codes, ", ") .. "}") end
end
register_postdissector(verdicts)

-- ---- where XA-C1 bytes come from -------------------------------------------------------------------

-- The line's direction is the RTAC serial event type (TX host, RX device; error events: the last data
-- direction). A payload dissector cannot see it when Wireshark builds no tree (a first pass), so a thin
-- dissector reads it from the RTAC header, then hands the packet to the RTAC serial dissector.
local line = Proto("xac1_line", "XA-C1 line direction (RTAC serial event type)")
local rtacser = Dissector.get("rtacser")
local RTAC_EVENT_OFFSET, RTAC_HEADER_LEN = 8, 12

function line.dissector(tvb, pinfo, tree)
  if not pinfo.visited and tvb:len() >= RTAC_HEADER_LEN then
    local d = DATA_EVENTS[tvb(RTAC_EVENT_OFFSET, 1):uint()]
    if d then last_dir = d end
    dirs[pinfo.number] = d or last_dir or "host"
  end
  return rtacser:call(tvb, pinfo, tree)
end

DissectorTable.get("rtacser.data"):add_for_decode_as(xac1)
-- RTAC serial files, and USER0 (147) files that carry the same RTAC serial header.
local encap = DissectorTable.get("wtap_encap")
encap:add(wtap_encaps.RTAC_SERIAL, line)
encap:add(wtap_encaps.USER0, line)
