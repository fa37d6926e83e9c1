<?xml version="1.0" encoding="UTF-8"?>
<ISO15745ProfileContainer xmlns="http://www.canopen.org/xml/1.0">
<ProfileBody fileName="a.xdc" fileVersion="1">
<DeviceIdentity><vendorName>V</vendorName><vendorID>0x1</vendorID></DeviceIdentity>
<parameter uniqueID="p1" access="readWrite"><UINT/><defaultValue value="7"/><allowedValues><range><minValue value="1"/><maxValue value="9"/></range></allowedValues></parameter>
</ProfileBody>
<ProfileBody>
<CANopenObjectList>
<CANopenObject index="1000" name="Device type" objectType="7" dataType="0007" accessType="ro" defaultValue="0x191"/>
<CANopenObject index="1018" name="Identity" objectType="9" subNumber="2">
<CANopenSubObject subIndex="00" name="Count" objectType="7" dataType="0005" accessType="ro" defaultValue="1"/>
<CANopenSubObject subIndex="01" name="Vendor" objectType="7" dataType="0007" accessType="ro" defaultValue="$NODEID+0x180" actualValue="0x185" PDOmapping="no"/>
</CANopenObject>
<CANopenObject index="2000" name="P" objectType="7" uniqueIDRef="p1" PDOmapping="TPDO" objFlags="1" denotation="d"/>
</CANopenObjectList>
<baudRate><supportedBaudRate value="250 Kbps"/></baudRate>
<dummyUsage><dummy entry="Dummy0002=1"/></dummyUsage>
<deviceCommissioning nodeID="5" actualBaudRate="250 Kbps" nodeName="n"/>
</ProfileBody>
</ISO15745ProfileContainer>
