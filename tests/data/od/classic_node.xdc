<?xml version="1.0" encoding="UTF-8"?>
<!-- Hand-written test file: a commissioned classic CANopen node (CiA 311 XDC). -->
<ISO15745ProfileContainer xmlns="http://www.canopen.org/xml/1.1" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <ISO15745Profile>
    <ProfileHeader>
      <ProfileIdentification>CANopen device profile</ProfileIdentification>
      <ProfileRevision>1.1</ProfileRevision>
      <ProfileName/>
      <ProfileSource/>
      <ProfileClassID>Device</ProfileClassID>
      <ISO15745Reference>
        <ISO15745Part>4</ISO15745Part>
        <ISO15745Edition>1</ISO15745Edition>
        <ProfileTechnology>CANopen</ProfileTechnology>
      </ISO15745Reference>
    </ProfileHeader>
    <ProfileBody xsi:type="ProfileBody_Device_CANopen" fileName="acme_valve.xdc" fileCreator="canopenfd tests" fileCreationDate="2026-02-01" fileVersion="2">
      <DeviceIdentity>
        <vendorName>Acme Valves AB</vendorName>
        <vendorID>0x000002B7</vendorID>
        <productName>Valve terminal VT-8</productName>
        <productID>0x00000808</productID>
        <orderNumber>VT8-C</orderNumber>
      </DeviceIdentity>
      <ApplicationProcess>
        <parameterList>
          <parameter uniqueID="UID_PARAM_1000" access="read">
            <label lang="en">Device type</label>
            <UDINT/>
            <defaultValue value="0x00000191"/>
          </parameter>
          <parameter uniqueID="UID_PARAM_2001" access="readWriteOutput">
            <label lang="en">Valve position</label>
            <INT/>
            <defaultValue value="0"/>
            <allowedValues>
              <range>
                <minValue value="-1000"/>
                <maxValue value="1000"/>
              </range>
            </allowedValues>
          </parameter>
        </parameterList>
      </ApplicationProcess>
    </ProfileBody>
  </ISO15745Profile>
  <ISO15745Profile>
    <ProfileHeader>
      <ProfileIdentification>CANopen communication network profile</ProfileIdentification>
      <ProfileRevision>1.1</ProfileRevision>
      <ProfileName/>
      <ProfileSource/>
      <ProfileClassID>CommunicationNetwork</ProfileClassID>
      <ISO15745Reference>
        <ISO15745Part>4</ISO15745Part>
        <ISO15745Edition>1</ISO15745Edition>
        <ProfileTechnology>CANopen</ProfileTechnology>
      </ISO15745Reference>
    </ProfileHeader>
    <ProfileBody xsi:type="ProfileBody_CommunicationNetwork_CANopen" fileName="acme_valve.xdc" fileCreator="canopenfd tests" fileCreationDate="2026-02-01" fileVersion="2">
      <ApplicationLayers>
        <identity>
          <vendorID>0x000002B7</vendorID>
        </identity>
        <CANopenObjectList mandatoryObjects="3" optionalObjects="4" manufacturerObjects="2">
          <CANopenObject index="1000" name="Device type" objectType="7" PDOmapping="no" uniqueIDRef="UID_PARAM_1000"/>
          <CANopenObject index="1001" name="Error register" objectType="7" dataType="0005" accessType="ro" PDOmapping="optional" defaultValue="0"/>
          <CANopenObject index="1014" name="COB-ID EMCY" objectType="7" dataType="0007" accessType="rw" PDOmapping="no" defaultValue="$NODEID+0x80" actualValue="0x000000A0"/>
          <CANopenObject index="1016" name="Consumer heartbeat time" objectType="8" subNumber="3">
            <CANopenSubObject subIndex="00" name="Number of entries" objectType="7" dataType="0005" accessType="ro" PDOmapping="no" defaultValue="2"/>
            <CANopenSubObject subIndex="01" name="Consumer heartbeat time 1" objectType="7" dataType="0007" accessType="rw" PDOmapping="no" defaultValue="0" actualValue="0x000101F4"/>
            <CANopenSubObject subIndex="02" name="Consumer heartbeat time 2" objectType="7" dataType="0007" accessType="rw" PDOmapping="no" defaultValue="0"/>
          </CANopenObject>
          <CANopenObject index="1017" name="Producer heartbeat time" objectType="7" dataType="0006" accessType="rw" PDOmapping="no" defaultValue="0" actualValue="500" lowLimit="0" highLimit="10000"/>
          <CANopenObject index="1018" name="Identity object" objectType="9" subNumber="3">
            <CANopenSubObject subIndex="00" name="Highest sub-index supported" objectType="7" dataType="0005" accessType="ro" PDOmapping="no" defaultValue="2"/>
            <CANopenSubObject subIndex="01" name="Vendor-ID" objectType="7" dataType="0007" accessType="ro" PDOmapping="no" defaultValue="0x000002B7"/>
            <CANopenSubObject subIndex="02" name="Product code" objectType="7" dataType="0007" accessType="ro" PDOmapping="no" defaultValue="0x00000808"/>
          </CANopenObject>
          <CANopenObject index="1800" name="TPDO communication parameter 1" objectType="9" subNumber="3">
            <CANopenSubObject subIndex="00" name="Highest sub-index supported" objectType="7" dataType="0005" accessType="ro" PDOmapping="no" defaultValue="2"/>
            <CANopenSubObject subIndex="01" name="COB-ID used by TPDO" objectType="7" dataType="0007" accessType="rw" PDOmapping="no" defaultValue="$NODEID+0x180" actualValue="$NODEID+0x180"/>
            <CANopenSubObject subIndex="02" name="Transmission type" objectType="7" dataType="0005" accessType="rw" PDOmapping="no" defaultValue="254" actualValue="1"/>
          </CANopenObject>
          <CANopenObject index="2001" name="Valve position" objectType="7" PDOmapping="TPDO" uniqueIDRef="UID_PARAM_2001" denotation="Main valve"/>
          <CANopenObject index="2002" name="Valve mode" objectType="7" dataType="0005" accessType="rww" PDOmapping="default" defaultValue="1" actualValue="3"/>
        </CANopenObjectList>
        <dummyUsage>
          <dummy entry="Dummy0001=0"/>
          <dummy entry="Dummy0005=1"/>
        </dummyUsage>
      </ApplicationLayers>
      <TransportLayers>
        <PhysicalLayer>
          <baudRate defaultValue="250 Kbps">
            <supportedBaudRate value="125 Kbps"/>
            <supportedBaudRate value="250 Kbps"/>
            <supportedBaudRate value="1000 Kbps"/>
          </baudRate>
        </PhysicalLayer>
      </TransportLayers>
      <NetworkManagement>
        <CANopenGeneralFeatures granularity="8" nrOfRxPDO="0" nrOfTxPDO="1" layerSettingServiceSlave="false"/>
        <deviceCommissioning nodeID="32" nodeName="valve_left" actualBaudRate="250 Kbps" networkNumber="1" networkName="line A" CANopenManager="false"/>
      </NetworkManagement>
    </ProfileBody>
  </ISO15745Profile>
</ISO15745ProfileContainer>
