-- The peer of the decode benchmark: a minimal XA-C1 dissector for tshark, as the issue measured it.
-- It splits an RTAC serial payload at LF and shows each line's 3-byte header; nothing more.
-- Use: tshark -r FILE -X lua_script:minimal_dissector.lua -d rtacser.data,xac1min -T fields -e xac1min.header
local p = Proto("xac1min", "XA-C1 (minimal benchmark dissector)")
local f_header = ProtoField.string("xac1min.header", "Header")
p.fields = { f_header }

function p.dissector(tvb, pinfo, tree)
    local len = tvb:len()
    local start = 0
    local subtree = tree:add(p, tvb())
    for i = 0, len - 1 do
        if tvb(i, 1):uint() == 10 then
            if i - start >= 2 then
                subtree:add(f_header, tvb(start, 3))
            end
            start = i + 1
        end
    end
    pinfo.cols.protocol = "XA-C1"
    return len
end

DissectorTable.get("rtacser.data"):add_for_decode_as(p)
